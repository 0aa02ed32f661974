"""Constraint handling: how a swarm ranks paths that may collide.

Every rule turns what the problem measures about a path (``Measured``: the objective 1 /
distance, the paper's fitness, the violation) into one score to maximise. Some rules change
over the run (epsilon) or adapt to it (penalty), so the swarm keeps each personal best's
measurements and scores them again at every iteration: all comparisons are made under the rule
of the moment. The rule is data (its index in ``CONSTRAINTS``, a traced int32 under jit), so
one compiled program serves every rule.

- ``"death"`` (the paper, eq. 17): score = fitness, 0 for any colliding path; an all-colliding
  swarm sees no difference between its particles.
- ``"feasibility"`` (Deb's feasibility rules): a collision-free path beats a colliding one;
  between free paths the higher fitness wins, between colliding ones the smaller violation.
  As one number: fitness if free, else ``-violation``.
- ``"epsilon"`` (Takahama and Sakai's epsilon-constrained comparison): paths whose violation
  is at most epsilon(t) compare by objective as if free; the others by violation. As one number:
  objective if ``violation <= epsilon(t)``, else ``-violation``. Schedule: epsilon(0) is the
  violation of the initial swarm's particle at the 20 % quantile of violation (theta = 0.2 N,
  as Takahama and Sakai); ``epsilon(t) = epsilon(0) (1 - t / Tc) ** 5`` for ``t < Tc`` and 0
  from ``Tc = n_iters / 2`` on (cp = 5; Tc is our choice for runs of ~100 iterations), so the
  second half of the run is the feasibility rules.
- ``"penalty"`` (an adaptive penalty, after Hadj-Alouane and Bean): score = ``objective -
  lambda * violation``. lambda(0) = mean objective / mean violation of the initial swarm (the
  two terms start balanced; 1 when no particle collides); after every update lambda doubles
  while the global best collides (up to 1e6 lambda(0)) and stays while it is free. (Halving it
  while free, as Hadj-Alouane and Bean do, let colliding paths win back the global best.)

What the rules compare as a path's violation (``path_measures``): its violation
(``jaxarm.violation``, the deepest penetration found, cm) times its travelling distance (the
paper's eq. 5, the denominator of its fitness), so the violation per unit of fitness. Between
two colliding paths as deep as each other, the shorter is the less violating. With the depth
alone, a colliding path could shed penetration by a long detour (joint 1 turned the wrong way
round the base on paper-case-1) into a local minimum of the depth, and feasibility rules followed
it there (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Constraint rules compare
depth x distance").

The reported fitness is always the paper's (0 for a colliding path) and the reported violation
the depth alone: a rule changes how the swarm moves, never what a path is worth.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.choices import CONSTRAINTS, one_of

EPSILON_QUANTILE = 0.2  # theta / N: the initial particle whose violation sets epsilon(0)
EPSILON_POWER = 5.0  # cp
EPSILON_END = 0.5  # Tc / n_iters
PENALTY_FACTOR = 2.0  # lambda's step up while the global best collides
PENALTY_MAX_RATIO = 1e6  # lambda stays <= lambda(0) * this (finite in float32)


class Measured(NamedTuple):
    """What the problem says about a batch of positions, each of shape (n,)."""

    objective: jax.Array  # to maximise when constraints are ignored (jaxarm: 1 / distance)
    fitness: jax.Array  # what is reported (the paper's eq. 17: 0 on collision)
    ranked_violation: jax.Array  # >= 0, 0 iff feasible: what the rules rank colliding paths
    #   by (jaxarm: depth x distance, ``path_measures``)
    violation: jax.Array  # what is reported (jaxarm: ``jaxarm.violation``, the depth, cm)


def path_measures(fitness, violation, distance) -> Measured:
    """What the rules compare about paths, from the problem's evaluation of them.

    Args:
      fitness: the paper's fitness, shape (n,).
      violation: the problem's violation (cm, 0 iff collision-free), shape (n,).
      distance: the travelling distance (paper eq. 5), shape (n,), > 0.

    Returns:
      ``Measured``: objective 1 / distance, the fitness, the violation times the distance, and
      the violation as given (reported).

    Examples:
      >>> deep_and_short, deep_and_long = path_measures(
      ...     jnp.zeros(2), jnp.array([1.0, 1.0]), jnp.array([4.0, 20.0])).ranked_violation.tolist()
      >>> deep_and_short < deep_and_long
      True
    """
    return Measured(objective=1.0 / distance, fitness=fitness, ranked_violation=violation * distance,
                    violation=violation)


class ConstraintState(NamedTuple):
    """What an adaptive rule remembers (scalars; unused by death and feasibility)."""

    epsilon0: jax.Array  # shape=(), epsilon(0)
    penalty0: jax.Array  # shape=(), lambda(0)
    penalty: jax.Array  # shape=(), lambda now


def constraint_index(constraint):
    """A rule given by name (its position in ``CONSTRAINTS``: how a compiled search receives
    it, as data) or already by index (an int, or traced), as its index."""
    if isinstance(constraint, str):
        return CONSTRAINTS.index(one_of("constraint", constraint, CONSTRAINTS))
    return constraint


def initial_state(measured: Measured) -> ConstraintState:
    """The adaptive rules' state from the initial swarm's measurements (shape (n_particles,))."""
    violation = measured.ranked_violation
    epsilon0 = jnp.sort(violation)[int(EPSILON_QUANTILE * (violation.shape[0] - 1))]
    mean_violation = jnp.mean(violation)
    balanced = jnp.mean(measured.objective) / jnp.where(mean_violation > 0, mean_violation, 1.0)
    usable = (mean_violation > 0) & jnp.isfinite(balanced) & (balanced > 0)
    penalty0 = jnp.where(usable, balanced, 1.0)
    return ConstraintState(epsilon0=epsilon0, penalty0=penalty0.astype(violation.dtype),
                     penalty=penalty0.astype(violation.dtype))


def epsilon_level(state: ConstraintState, iteration, n_iters: int) -> jax.Array:
    """epsilon(t) of the schedule above (shape ())."""
    end = EPSILON_END * n_iters
    remaining = jnp.clip(1.0 - iteration / end, 0.0, 1.0)
    return state.epsilon0 * remaining ** EPSILON_POWER


def score(constraint, state: ConstraintState, measured: Measured, iteration, n_iters: int):
    """The scores of ``measured`` (shape (n,)) under the rule at update ``iteration``.

    Examples:
      >>> free_and_colliding = Measured(jnp.array([5.0, 8.0]), jnp.array([5.0, 0.0]),
      ...                               jnp.array([0.0, 3.0]), jnp.array([0.0, 3.0]))
      >>> state = initial_state(free_and_colliding)
      >>> score("feasibility", state, free_and_colliding, 1, 100).tolist()
      [5.0, -3.0]
    """
    index = constraint_index(constraint)
    fitness, violation, objective = measured.fitness, measured.ranked_violation, measured.objective
    feasible = violation == 0
    epsilon = epsilon_level(state, iteration, n_iters)
    by_rule = [
        fitness,  # death
        jnp.where(feasible, fitness, -violation),  # feasibility
        jnp.where(violation <= epsilon, objective, -violation),  # epsilon
        objective - state.penalty * violation,  # penalty
    ]
    result = by_rule[0]
    for rule, value in enumerate(by_rule[1:], start=1):
        result = jnp.where(index == rule, value, result)
    return jnp.where(jnp.isfinite(result), result, -jnp.inf)  # NaN never becomes a best


def updated_state(state: ConstraintState, global_feasible) -> ConstraintState:
    """lambda after an update whose global best is (or is not) collision-free."""
    raised = jnp.minimum(state.penalty * PENALTY_FACTOR, state.penalty0 * PENALTY_MAX_RATIO)
    return state._replace(penalty=jnp.where(global_feasible, state.penalty, raised))
