"""The optimiser protocol: what the restart loop (``jaxarm.optim.restarts``) runs.

An optimiser is a set of pure functions over a state (a pytree), as optax's
``GradientTransformation`` and blackjax's ``SamplingAlgorithm`` are:

- ``init(key) -> (state, x)``: the paths of iteration 0, shape (population, n_free), and a
  state awaiting their measurement;
- ``tell(state, x, measured, iteration) -> (state, info)``: what ``measure(x)`` found at
  ``iteration`` (0: the initial paths), and a ``StepInfo`` for the loop to record;
- ``ask(key, state) -> (state, x)``: the next paths;
- ``measure``: paths (population, n_free) -> ``Measured``;
- ``bar`` (optional): ``bar(state) -> Bar``, what each particle's next path must do to change
  the state, so that the loop need not prove the others.

PSO (``jaxarm.optim.pso.swarm``), evosax's strategies (``jaxarm.optim.evosax_adapter``) and
users' own optimisers (``jaxarm.optim.custom``, written to a simpler public protocol) implement
it; ``restarts.run_restarts_of`` runs any optimiser given this way, vmapped over
restarts and scanned over iterations. Each function sees one restart. ``iteration`` is the
loop's counter, the same for every restart, so a branch on it runs one side only under
``vmap`` (``on_first_iteration``).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.optim.constraints import Measured, constraint_index

MeasureFn = Callable[[jax.Array], Measured]


class StepInfo(NamedTuple):
    """Per-iteration diagnostics (not part of the state): what the restart loop records."""

    global_position: jax.Array  # shape=(n_free,), the best path so far
    global_fitness: jax.Array  # shape=(), its fitness
    global_violation: jax.Array  # shape=(), its reported violation (0 iff feasible)
    global_score: jax.Array  # shape=(), its score
    n_feasible: jax.Array  # shape=(), int32: paths measured feasible at this iteration
    #   (a path left unmeasured because it could not change the state, ``Bar``, is not)


class Bar(NamedTuple):
    """What a particle's next path must do to change the optimiser's state, each field of shape
    (population,)."""

    objective: jax.Array  # exceed this objective (a path that does not changes nothing)
    free_only: jax.Array  # bool: only a free path can change it (a colliding one's violation
    #   does not matter)


class Optimizer(NamedTuple):
    """An optimiser as pure ask-and-tell functions and the measurement its paths get (module
    docstring).

    ``bar`` None: every path may change the state (evosax's strategies rank them all). With a
    bar, a restart loop given a measurement that accepts it may leave the other paths unproved,
    and stop proving a path that can only matter if free once it is found not to be: the
    certified check's proofs are most of a certified search.

    ``begin`` and ``step`` measure and tell one iteration, for stepping by hand.
    """

    init: Callable
    tell: Callable
    ask: Callable
    measure: MeasureFn
    bar: Callable | None = None

    def begin(self, key) -> tuple:
        """Iteration 0, measured: ``(state, info)``."""
        state, x = self.init(key)
        return self.tell(state, x, self.measure(x), 0)

    def step(self, key, state, iteration) -> tuple:
        """Iteration ``iteration`` (>= 1), measured: ``(state, info)``."""
        state, x = self.ask(key, state)
        return self.tell(state, x, self.measure(x), iteration)


def on_first_iteration(iteration, first: Callable, later: Callable):
    """``first()`` at iteration 0, else ``later()``.

    A Python choice for a concrete iteration (stepping by hand), else ``lax.cond``: the loop's
    counter is the same for every restart, so only one side runs (a select would compute the
    initial state at every update: ``benchmarks/pso_speed.py``).
    """
    if isinstance(iteration, int):
        return first() if iteration == 0 else later()
    return jax.lax.cond(iteration == 0, first, later)


class Best(NamedTuple):
    """The lowest-cost path an optimiser has been told of (for optimisers that keep no best of
    their own: evosax's strategies and users' own), each field of one restart."""

    x: jax.Array  # shape=(n_free,)
    cost: jax.Array  # shape=(), ``rule_cost`` (inf before the first tell)
    fitness: jax.Array  # shape=(), paper eq. 17 fitness of x
    violation: jax.Array  # shape=(), its reported violation


def no_best(x) -> Best:
    """Before the first tell (nothing kept: infinitely colliding); x (population, n_free)
    gives the shapes."""
    inf = jnp.asarray(jnp.inf, x.dtype)
    return Best(x=x[0], cost=inf, fitness=jnp.zeros((), x.dtype), violation=inf)


def rule_cost(measured: Measured, constraint) -> jax.Array:
    """Costs to minimise under the death penalty (``-fitness``: every colliding path 0) or
    feasibility rules (``-fitness`` when free, else the ranked violation, > 0: a free path beats
    every colliding one, and less violation beats more: Deb's rules as one number);
    ``constraint``: ``constraint_index`` of either (data)."""
    feasibility = jnp.asarray(constraint) == constraint_index("feasibility")
    cost = jnp.where(feasibility & (measured.ranked_violation > 0), measured.ranked_violation,
                     -measured.fitness)
    # A path measured NaN (non-finite coefficients from an optimiser, or ones that overflow) is
    # the worst, never a free path of fitness 0 (NaN > 0 is false).
    return jnp.where(jnp.isnan(measured.ranked_violation) | jnp.isnan(measured.fitness),
                     jnp.inf, cost)


def told_best(best: Best, x, cost, measured: Measured) -> tuple[Best, StepInfo]:
    """``best`` after paths x (population, n_free) of these costs (the first on ties; a NaN
    cost counts as inf), and the ``StepInfo`` the restart loop records."""
    cost = jnp.where(jnp.isnan(cost), jnp.inf, cost)
    index = jnp.argmin(cost)
    better = cost[index] < best.cost
    keep = lambda new, old: jnp.where(better, new, old)  # noqa: E731
    best = Best(keep(x[index], best.x), keep(cost[index], best.cost),
                keep(measured.fitness[index], best.fitness),
                keep(measured.violation[index], best.violation))
    return best, StepInfo(global_position=best.x, global_fitness=best.fitness,
                          global_violation=best.violation, global_score=-best.cost,
                          n_feasible=(measured.ranked_violation == 0).sum(dtype=jnp.int32))
