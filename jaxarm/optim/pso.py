"""Particle Swarm Optimization as pure functions (paper eqs. 13-16), maximising a score.

One formula covers the paper's three velocity rules:

    v <- chi * (omega(t) * v + phi1 * beta1 * (p_i - x) + phi2 * beta2 * (p_g - x)),  x <- x + v

- ``"original"`` (eq. 13): chi = 1, omega = 1.
- ``"inertia"`` (eq. 15): chi = 1, omega(t) linear from ``inertia_start`` (t = 0) to
  ``inertia_end`` (t = n_iters); the paper's ``(maxit - iter) / maxit`` is 1 -> 0, a constant
  weight is start == end.
- ``"constriction"`` (eq. 16): ``chi = 2 / |2 - phi - sqrt(phi^2 - 4 phi)|`` with
  ``phi = phi1 + phi2 > 4`` (the paper's formula without the absolute value would make chi
  negative), omega(t) as for inertia.

Update t (t = 1 .. n_iters) uses omega(t). The swarm is synchronous: all particles move, then
all are evaluated, then personal bests (replaced only on a strictly better score) and the global
best (the best personal best) are updated.

Choices the paper leaves open, with its defaults: initial velocity zero (``init_velocity``, a
fraction of the init range), no velocity clamp (``velocity_clamp``, a fraction of the init
range), ``beta`` drawn per dimension (or once per particle), and ties for the global best broken
by the first index, as MATLAB's ``max`` (or uniformly at random). Under the death penalty an
all-infeasible swarm has all-equal scores, so with first-index ties the global best stays at
particle 0's initial position until some particle becomes feasible; personal bests never move
either. That is the paper's behaviour (escape by the swarm's own random motion), and it is the
pitfall evosax fixed in its PR #109; ``tie_break="random"`` is the alternative.

Topology: ``"global"`` (the paper's gbest: every particle follows the swarm's best personal
best), ``"ring"`` (lbest: particle i follows the best personal best among particles i - 1, i
and i + 1, indices modulo n) or ``"global-ring"``: the global best for the first
``GLOBAL_RING_SHARE`` (5 %) of the iterations, the ring after (why 5 %, and what it does
now: ``benchmarks/RESULTS.md``, *Decisions and negative results*, "global-ring's 5 %"). The
reported global best is the swarm's best personal best either way.

Scores come from a constraint-handling rule (``jaxarm.optim.constraints``) applied to what the
measure function reports; every personal best is scored again at every update, so rules that
change over the run compare like with like. A non-finite score (NaN or inf coordinates, say)
counts as -inf, so it never becomes a personal or global best.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._validate import representable
from jaxarm.choices import (
    BETA_MODES,
    TIE_BREAKS,
    TOPOLOGIES,
    VELOCITY_RULES,
    one_of,
)
from jaxarm.optim import constraints
from jaxarm.optim.base import Bar, MeasureFn, Optimizer, StepInfo, on_first_iteration
from jaxarm.optim.constraints import Measured


class PSOParams(NamedTuple):
    """The numeric part of a PSO variant: data under jit, so every preset shares one program."""

    constriction: jax.Array  # shape=(), chi (1 unless the constriction rule)
    inertia_start: jax.Array  # shape=(), omega at t = 0 (1 for the original rule)
    inertia_end: jax.Array  # shape=(), omega at t = n_iters (1 for the original rule)
    cognitive_coeff: jax.Array  # shape=(), phi1
    social_coeff: jax.Array  # shape=(), phi2
    init_velocity: jax.Array  # shape=(), initial speed as a fraction of the init range
    velocity_clamp: jax.Array  # shape=(), clamp as a fraction of the init range (inf: none)
    ring_from: jax.Array  # shape=(), the ring (lbest) follows iterations > ring_from * n_iters


class SwarmRules(NamedTuple):
    """The static part of a PSO variant: what changes the compiled program."""

    tie_break: str  # "first" or "random"
    beta: str  # "dimension" or "particle"


class PSOConfig(NamedTuple):
    """A PSO variant. Field names follow evosax (``cognitive_coeff`` is the paper's phi1 / c1).

    Examples:
      >>> PSOConfig(velocity_rule="constriction", cognitive_coeff=3.0, social_coeff=2.0,
      ...           inertia_start=1.0, inertia_end=1.0).constriction  # doctest: +ELLIPSIS
      0.3819...
    """

    velocity_rule: str = "inertia"
    cognitive_coeff: float = 1.5
    social_coeff: float = 1.5
    inertia_start: float = 1.0
    inertia_end: float = 0.0
    init_velocity: float = 0.0
    velocity_clamp: float | None = None
    tie_break: str = "first"
    beta: str = "dimension"
    topology: str = "global"

    @property
    def constriction(self) -> float:
        """chi: 1 unless ``velocity_rule == "constriction"``."""
        if self.velocity_rule != "constriction":
            return 1.0
        phi = self.cognitive_coeff + self.social_coeff
        return 2.0 / abs(2.0 - phi - math.sqrt(phi * phi - 4.0 * phi))

    def validate(self) -> "PSOConfig":
        """Return self, or raise ValueError naming the bad field and value."""
        one_of("velocity_rule", self.velocity_rule, VELOCITY_RULES)
        one_of("tie_break", self.tie_break, TIE_BREAKS)
        one_of("beta", self.beta, BETA_MODES)
        one_of("topology", self.topology, TOPOLOGIES)
        for name in ("cognitive_coeff", "social_coeff", "inertia_start", "inertia_end",
                     "init_velocity"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
            representable(name, value)  # the search runs in float32
        if self.velocity_clamp is not None and not (
            isinstance(self.velocity_clamp, (int, float)) and 0 < self.velocity_clamp < math.inf
        ):
            raise ValueError(f"velocity_clamp must be None or > 0, got {self.velocity_clamp!r}")
        if self.velocity_clamp is not None:
            representable("velocity_clamp", self.velocity_clamp)
        if self.velocity_rule == "constriction" and self.cognitive_coeff + self.social_coeff <= 4:
            raise ValueError(
                "constriction needs cognitive_coeff + social_coeff > 4, got "
                f"{self.cognitive_coeff} + {self.social_coeff}"
            )
        return self

    def params(self) -> PSOParams:
        """The numeric part, as scalars of JAX's default float type."""
        original = self.velocity_rule == "original"
        values = PSOParams(
            constriction=self.constriction,
            inertia_start=1.0 if original else self.inertia_start,
            inertia_end=1.0 if original else self.inertia_end,
            cognitive_coeff=self.cognitive_coeff,
            social_coeff=self.social_coeff,
            init_velocity=self.init_velocity,
            velocity_clamp=math.inf if self.velocity_clamp is None else self.velocity_clamp,
            ring_from=RING_FROM[self.topology],
        )
        return PSOParams(*(np.asarray(v, dtype=jnp.result_type(float)) for v in values))

    def rules(self) -> SwarmRules:
        """The static part."""
        return SwarmRules(tie_break=self.tie_break, beta=self.beta)


GLOBAL_RING_SHARE = 0.05  # "global-ring": the share of the iterations that follow the global best
# The share of the iterations before the ring topology takes over (inf: never).
RING_FROM = {"global": math.inf, "ring": 0.0, "global-ring": GLOBAL_RING_SHARE}

# The paper's Table 2 presets.
PRESETS = {
    "A": PSOConfig(velocity_rule="inertia", cognitive_coeff=1.5, social_coeff=1.5,
                   inertia_start=1.0, inertia_end=0.0),
    "B": PSOConfig(velocity_rule="inertia", cognitive_coeff=0.5, social_coeff=0.5,
                   inertia_start=1.0, inertia_end=0.0),
    "C": PSOConfig(velocity_rule="constriction", cognitive_coeff=3.0, social_coeff=2.0,
                   inertia_start=1.0, inertia_end=1.0),
}


class SwarmState(NamedTuple):
    """A swarm between two updates."""

    position: jax.Array  # shape=(n_particles, n_dims)
    velocity: jax.Array  # shape=(n_particles, n_dims)
    best_position: jax.Array  # shape=(n_particles, n_dims), personal bests
    best: Measured  # each field shape=(n_particles,): the personal bests' measurements
    best_score: jax.Array  # shape=(n_particles,), their scores under the rule of this update
    global_index: jax.Array  # shape=(), int32: particle whose personal best is the global best
    iteration: jax.Array  # shape=(), int32: updates done so far (0: the initial swarm)
    constraint_state: constraints.ConstraintState  # what an adaptive constraint rule remembers
    tie_key: jax.Array  # the key that breaks ties for the global best when ``position`` is told


class _Setting(NamedTuple):
    """What every function of one swarm reads (``swarm``'s arguments)."""

    params: PSOParams
    rules: SwarmRules
    low: jax.Array  # shape=(1, n_dims): rows, like positions
    high: jax.Array  # shape=(1, n_dims)
    n_particles: int
    n_iters: int
    constraint: object  # a name from ``CONSTRAINTS`` or its index (may be traced)


def swarm(params: PSOParams, rules: SwarmRules, measure_fn: MeasureFn, low, high, *,
          n_particles: int, n_iters: int, init_particles=None, n_given=None,
          constraint="death") -> Optimizer:
    """PSO over the box [low, high] as an ``Optimizer`` (paper eqs. 13-16).

    Args:
      params: ``PSOConfig.params()`` (traced).
      rules: ``PSOConfig.rules()`` (static).
      measure_fn: maps positions (n_particles, n_dims) to ``constraints.Measured``.
      low: the initial range's low end, shape (n_dims,).
      high: its high end, shape (n_dims,).
      n_particles: swarm size (static).
      n_iters: total number of updates, for the inertia and epsilon schedules (static).
      init_particles: optional given particles, shape (k, n_dims), k <= n_particles; the first
        ``n_given`` of them (default: all k) replace the first random ones (paper Table 6).
      n_given: how many rows of ``init_particles`` to use (may be traced, so that one program
        serves any number of given particles).
      constraint: a name from ``CONSTRAINTS`` or its index (may be traced).

    Returns:
      ``Optimizer``; ``init`` draws iteration 0, each ``ask`` one synchronous update.

    Examples:
      >>> def sphere(x):
      ...     value = -(x ** 2).sum(-1)
      ...     violation = jnp.where(x[:, 0] > 0, 0.0, 1.0)
      ...     return Measured(value, value, violation, violation)
      >>> config = PRESETS["A"]
      >>> pso = swarm(config.params(), config.rules(), sphere, -jnp.ones(2), jnp.ones(2),
      ...             n_particles=5, n_iters=10)
      >>> state, info = pso.begin(jax.random.key(0))
      >>> state, info = pso.step(jax.random.key(1), state, 1)
      >>> int(state.iteration)
      1
    """
    setting = _Setting(params, rules, jnp.reshape(low, (1, -1)), jnp.reshape(high, (1, -1)),
                       n_particles, n_iters, constraint)
    return Optimizer(init=functools.partial(_init, setting, init_particles, n_given),
                     tell=functools.partial(_tell, setting),
                     ask=functools.partial(_ask, setting), measure=measure_fn,
                     bar=functools.partial(_bar, setting))


def _init(setting: _Setting, init_particles, n_given, key) -> tuple[SwarmState, jax.Array]:
    """Iteration 0's positions (uniform in the box, the given particles first) and velocities."""
    low, high, n_particles = setting.low, setting.high, setting.n_particles
    position_key, velocity_key, tie_key = jax.random.split(key, 3)
    span = high - low
    position = low + span * jax.random.uniform(position_key, (n_particles, low.shape[-1]),
                                               dtype=low.dtype)
    if init_particles is not None:
        count = init_particles.shape[0] if n_given is None else n_given
        given = jnp.zeros_like(position).at[: init_particles.shape[0]].set(
            init_particles.astype(low.dtype))
        position = jnp.where(jnp.arange(n_particles)[:, None] < count, given, position)
    velocity = setting.params.init_velocity * span * jax.random.uniform(
        velocity_key, position.shape, dtype=low.dtype, minval=-1.0, maxval=1.0
    )
    zeros = jnp.zeros(n_particles, low.dtype)
    scalar = jnp.zeros((), low.dtype)
    state = SwarmState(  # nothing measured yet: ``tell`` replaces every best
        position=position,
        velocity=velocity,
        best_position=position,
        best=Measured(zeros, zeros, zeros, zeros),
        best_score=zeros,
        global_index=jnp.zeros((), jnp.int32),
        iteration=jnp.zeros((), jnp.int32),
        constraint_state=constraints.ConstraintState(scalar, scalar, scalar),
        tie_key=tie_key,
    )
    return state, position


def _ask(setting: _Setting, key, state: SwarmState) -> tuple[SwarmState, jax.Array]:
    """One synchronous update of every particle's velocity and position (eqs. 13-16)."""
    params, n_iters = setting.params, setting.n_iters
    beta_key, tie_key = jax.random.split(key)
    shape = state.position.shape
    beta_shape = shape if setting.rules.beta == "dimension" else shape[:1] + (1,)
    beta1, beta2 = jax.random.uniform(beta_key, (2,) + beta_shape, dtype=state.position.dtype)
    iteration = state.iteration + 1
    omega = (params.inertia_start
             + (params.inertia_end - params.inertia_start) * iteration / n_iters)
    social = _social_attractor(state, iteration > params.ring_from * n_iters)
    velocity = params.constriction * (
        omega * state.velocity
        + params.cognitive_coeff * beta1 * (state.best_position - state.position)
        + params.social_coeff * beta2 * (social - state.position)
    )
    limit = params.velocity_clamp * (setting.high - setting.low)
    velocity = jnp.clip(velocity, -limit, limit).astype(state.position.dtype)
    position = state.position + velocity
    return state._replace(position=position, velocity=velocity, iteration=iteration,
                          tie_key=tie_key), position


def _tell(setting: _Setting, state: SwarmState, x, measured: Measured,
          iteration) -> tuple[SwarmState, StepInfo]:
    """Personal and global bests after the paths ``x`` measured ``measured``."""
    first = iteration == 0  # the initial swarm: its positions are its bests
    constraint_state = on_first_iteration(
        iteration, lambda: constraints.initial_state(measured), lambda: state.constraint_state)
    # new positions and personal bests compared under the rule of this update
    score = constraints.score(setting.constraint, constraint_state, measured, iteration,
                              setting.n_iters)
    old_score = constraints.score(setting.constraint, constraint_state, state.best, iteration,
                                  setting.n_iters)
    improved = first | (score > old_score)
    best_score = jnp.where(improved, score, old_score)
    best = jax.tree.map(lambda new, old: jnp.where(improved, new, old), measured,
                        state.best)
    feasible = measured.ranked_violation == 0
    global_index = _choose_global(state.tie_key, best_score, setting.rules.tie_break)
    updated = constraints.updated_state(constraint_state,
                                        best.ranked_violation[global_index] == 0)
    new_state = state._replace(
        position=x,
        best_position=jnp.where(improved[:, None], x, state.best_position),
        best=best,
        best_score=best_score,
        global_index=global_index,
        constraint_state=jax.tree.map(lambda kept, new: jnp.where(first, kept, new),
                                      constraint_state, updated),
    )
    return new_state, _info(new_state, feasible)


def _bar(setting: _Setting, state: SwarmState) -> Bar:
    """Per particle, the objective its next path must exceed to change the state, and whether
    only a free path can."""
    # A path changes the state only by beating its particle's personal best. Under every
    # rule a path scores at most its objective, and a feasible one scores its objective
    # (its fitness under the death penalty and feasibility rules, the same number), so
    # against a feasible personal best (ranked violation 0: obstacles and joint limits) a
    # path needs a higher objective. Iteration 0 replaces every best.
    later = state.iteration > 0
    feasible = (state.best.ranked_violation == 0) & later
    # A colliding path's violation matters only to rules that compare it with the best's:
    # not to the death penalty (every colliding path scores 0, no more than any best
    # after iteration 0), nor to feasibility rules against a feasible best.
    constraint = constraints.constraint_index(setting.constraint)
    free_only = later & ((constraint == constraints.constraint_index("death"))
                         | ((constraint == constraints.constraint_index("feasibility"))
                            & feasible))
    return Bar(objective=jnp.where(feasible, jnp.minimum(state.best.objective,
                                                         state.best.fitness), -jnp.inf),
               free_only=free_only)


def _social_attractor(state: SwarmState, ring) -> jax.Array:
    """What each particle's social term pulls towards, shape (n_particles, n_dims).

    ``ring`` false (global): the global best. True: the best personal best among the particle
    and its two ring neighbours (first index on ties: i - 1, then i, then i + 1). The topology
    is data (a traced bool), so both share one compiled program.
    """
    n = state.best_score.shape[0]
    particles = jnp.arange(n)
    neighbours = jnp.stack([(particles - 1) % n, particles, (particles + 1) % n], axis=1)
    choice = jnp.argmax(state.best_score[neighbours], axis=1)
    neighbourhood = jnp.where(ring, neighbours[particles, choice], state.global_index)
    return state.best_position[neighbourhood]


def _choose_global(key, best_score, tie_break: str):
    if tie_break == "first":
        return jnp.argmax(best_score).astype(jnp.int32)
    noise = jax.random.uniform(key, best_score.shape)
    return jnp.argmax(jnp.where(best_score == best_score.max(), noise, -1.0)).astype(jnp.int32)


def _info(state: SwarmState, feasible) -> StepInfo:
    return StepInfo(
        global_position=state.best_position[state.global_index],
        global_fitness=state.best.fitness[state.global_index],
        global_violation=state.best.violation[state.global_index],
        global_score=state.best_score[state.global_index],
        n_feasible=feasible.sum().astype(jnp.int32),
    )
