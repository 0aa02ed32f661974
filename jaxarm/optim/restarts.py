"""Independent restarts of a swarm in one compiled program: vmapped, scanned, sharded.

Restarts run side by side, the swarm's functions vmapped over them (and sharded over all devices
when there are several); iterations run in ``lax.scan``. Restart i draws everything from
``fold_in(key(seed), i)`` (and iteration t from ``fold_in`` of that with t), so its result does
not depend on how many restarts run beside it or how they are chunked. The compiled program is
specialised only on sizes and modes (``ProblemSpec``, particles, iterations, restarts and the
swarm's rules); angles, obstacles, PSO coefficients, the constraint rule, the init range and the
seed are data, so a new scenario or preset reuses it.

``run_restarts_of`` knows nothing about PSO: any optimiser given as a ``base.Optimizer`` (ask
and tell functions and the measurement) runs in the same loop.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._compile.padding import round_up
from jaxarm.checks.evaluate import ProofRequest, compiles_best_at_default_level, vmapped_evaluate
from jaxarm.model.problem import Problem, ProblemArrays, ProblemSpec
from jaxarm.optim import constraints, custom, evosax_adapter, pso
from jaxarm.optim.base import Optimizer, StepInfo
from jaxarm.optim.constraints import constraint_index

N_PARTICLES = 20  # the swarm size solve and escape_study use unless told
N_ITERS = 100  # their iterations per restart


class RestartOutcome(NamedTuple):
    """What each restart ended with (leading axis n_restarts)."""

    best_x: jax.Array  # shape=(n_restarts, n_free), the global best
    best_fitness: jax.Array  # shape=(n_restarts,), paper eq. 17 fitness of best_x
    best_violation: jax.Array  # shape=(n_restarts,), 0 iff best_x is collision-free
    escape_iter: jax.Array  # shape=(n_restarts,), int32, first feasible iteration; -1 if never
    escape_x: jax.Array  # shape=(n_restarts, n_free), global best at escape; NaN if never
    history: jax.Array  # shape=(n_restarts, n_iters + 1), global-best fitness per iteration

    @property
    def feasible(self) -> np.ndarray:
        """Shape (n_restarts,), bool: the restart's best path is collision-free."""
        return np.asarray(self.best_violation) == 0

    def best_restart(self) -> int:
        """Highest fitness among feasible restarts, else least violation; first index on ties."""
        return int(np.argmax(np.where(self.feasible, self.best_fitness, -self.best_violation)))

    def concatenate(self, *others: "RestartOutcome") -> "RestartOutcome":
        """This outcome followed by ``others``' restarts, as NumPy arrays."""
        return RestartOutcome(*(np.concatenate(parts) for parts in zip(self, *others)))


def run_restarts_of(keys, optimizer: Optimizer, n_iters: int,
                    measure_above=None) -> RestartOutcome:
    """Restarts, one per key: iteration 0 then ``n_iters`` updates, tracking escape and the
    best fitness.

    The loop runs on all restarts at once, the optimiser's functions mapped over them (a
    ``vmap`` of a one-restart loop gave the same bits but traced the loop's body twice more, in
    JAX's scan batching rule). The paths are measured at one place (in the loop's body), so a
    compiled program holds one copy of the measurement.

    Args:
      keys: one key per restart, shape (n_restarts,) (or raw uint32 keys, (n_restarts, 2));
        a restart's ``init`` gets ``fold_in(key, 0)``, the ask of update t
        ``fold_in(key, t)``.
      optimizer: the optimiser (its functions see one restart).
      n_iters: updates (static).
      measure_above: optionally ``(x, bar) -> Measured``, called in place of
        ``optimizer.measure`` with ``optimizer.bar(state)`` (a ``base.Bar``, when the optimiser
        has one), once for all the restarts (x of shape (n_restarts, n, n_free), the bar's
        fields and the result's (n_restarts, n)): it must measure as ``optimizer.measure``
        does every path whose objective exceeds its particle's bar (where ``bar.free_only``, at
        least whether the path is free, and some positive violation if not), and may leave the
        others unproved (violation inf); the loop returns the same.

    Returns:
      ``RestartOutcome``: best_x (n_restarts, n_free), its fitness and violation as the
      optimiser measured them (n_restarts,), escape_iter (n_restarts,), escape_x (n_restarts,
      n_free), history (n_restarts, n_iters + 1).
    """
    init, ask = jax.vmap(optimizer.init), jax.vmap(optimizer.ask)
    if measure_above is None or optimizer.bar is None:
        measure_all = jax.vmap(optimizer.measure)
        measure = lambda x, state: measure_all(x)  # noqa: E731
    else:
        # Not a ``vmap`` of a one-restart measurement: its batching rule folds the restarts
        # into one batch too, but JAX traces the check once more for the rule.
        bar = jax.vmap(optimizer.bar)
        measure = lambda x, state: measure_above(x, bar(state))  # noqa: E731
    tell = jax.vmap(optimizer.tell, in_axes=(0, 0, 0, None))
    keys_at = jax.vmap(jax.random.fold_in, in_axes=(0, None))
    state, x = init(keys_at(keys, 0))
    batch = x.shape[:1]  # (n_restarts,): typed keys or raw uint32 ones (n_restarts, 2)
    zero = jnp.zeros(batch, x.dtype)
    nan = jnp.full(batch + x.shape[-1:], jnp.nan, x.dtype)
    nothing_yet = StepInfo(global_position=nan, global_fitness=zero, global_violation=zero,
                           global_score=zero, n_feasible=jnp.zeros(batch, jnp.int32))

    def body(carry, iteration):
        state, x, _, escape_iter, escape_x = carry
        state, info = tell(state, x, measure(x, state), iteration)
        escaped_now = (escape_iter < 0) & (info.n_feasible > 0)
        escape_iter = jnp.where(escaped_now, iteration, escape_iter)
        escape_x = jnp.where(escaped_now[:, None], info.global_position, escape_x)
        # the last iteration's ask is not measured: it keeps the loop's body in one piece
        state, x = ask(keys_at(keys, iteration + 1), state)
        return (state, x, info, escape_iter, escape_x), info.global_fitness

    (_, _, info, escape_iter, escape_x), history = jax.lax.scan(
        body, (state, x, nothing_yet, jnp.full(batch, -1, jnp.int32), nan),
        jnp.arange(n_iters + 1))
    return RestartOutcome(info.global_position, info.global_fitness, info.global_violation,
                          escape_iter, escape_x, history.T)


class SearchData(NamedTuple):
    """The data of a search besides the problem's: changing any of it compiles nothing."""

    low: jax.Array  # shape=(n_free,), the init range
    high: jax.Array  # shape=(n_free,)
    seed: jax.Array  # shape=(), int32
    restart_ids: jax.Array  # shape=(n_restarts,), int32; restart i uses fold_in(key(seed), i)
    init_particles: jax.Array  # shape=(n_particles, n_free); its first n_given rows replace
    #   the first random particles (data: one program for any number of given particles)
    n_given: jax.Array  # shape=(), int32
    constraint: jax.Array  # shape=(), int32: ``constraints.constraint_index`` of the rule
    #   (data: every rule shares one program)


def search_restarts(spec: ProblemSpec, arrays: ProblemArrays, params: pso.PSOParams,
                    rules: pso.SwarmRules, data: SearchData, *, n_particles: int,
                    n_iters: int, xla_default_level: bool = False) -> RestartOutcome:
    """Run the PSO restarts numbered ``data.restart_ids`` (pure; ``compiled_search`` is its
    jit).

    Args:
      spec: static problem part; arrays: its data.
      params, rules: ``PSOConfig.params()`` and ``.rules()``, or an evosax
        ``evosax_adapter.StrategyConfig``'s or a user's ``custom.CustomConfig``'s (``rules`` is
        then the config itself; n_particles its population).
      data: ``SearchData``.
      n_particles, n_iters: static sizes.
      xla_default_level: static, read by ``compiled_search`` only: compile at XLA's default
        optimisation level (``checks.evaluate.compiles_best_at_default_level``).

    Returns:
      ``RestartOutcome`` with leading axis n_restarts.
    """
    low, high, seed, restart_ids, init_particles, n_given, constraint = data
    measure = path_measurement(spec, arrays)
    if isinstance(rules, evosax_adapter.StrategyConfig):  # "evosax:<Strategy>"
        optimizer = evosax_adapter.strategy_swarm(rules, measure, low, high,
                                                  n_particles=n_particles, constraint=constraint)
    elif isinstance(rules, custom.CustomConfig):  # the user's own
        optimizer = custom.custom_swarm(rules, path_evaluation(spec, arrays), low, high,
                                        constraint=constraint)
    else:
        optimizer = pso.swarm(params, rules, measure, low, high, n_particles=n_particles,
                              n_iters=n_iters, init_particles=init_particles, n_given=n_given,
                              constraint=constraint)

    keys = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.key(seed), restart_ids)
    return run_restarts_of(keys, optimizer, n_iters, measure_above=measure)


def path_measurement(spec: ProblemSpec, arrays: ProblemArrays):
    """What a search measures of its paths: ``(x, bar=None) -> constraints.Measured`` for x of
    shape (..., n, n_free) (one restart's paths, or every restart's at once: one batch, also
    under ``jax.vmap``); ``bar`` (a ``base.Bar``, the optimiser's) becomes the certified
    check's ``ProofRequest``, so that it skips what cannot change the optimiser's state
    (``checks.evaluate.evaluate``)."""
    evaluate = vmapped_evaluate(spec)

    def measure(x, bar=None):
        request = None if bar is None else ProofRequest(objective_above=bar.objective,
                                                        free_only=bar.free_only)
        evaluation = evaluate(arrays, x, request)
        return constraints.path_measures(evaluation.fitness, evaluation.violation,
                                         evaluation.distance)

    return measure


def path_evaluation(spec: ProblemSpec, arrays: ProblemArrays):
    """What a search tells a user's optimiser (``custom``) of its paths: ``x ->
    jaxarm.Evaluation``, every path proved in full, measured as ``path_measurement`` does."""
    evaluate = vmapped_evaluate(spec)
    return lambda x: evaluate(arrays, x)


compiled_search = jit(
    search_restarts, static_argnames=("spec", "rules", "n_particles", "n_iters",
                                      "xla_default_level"),
    storable=True, level_flag="xla_default_level", label="the search",
)


RESTART_BLOCK = 8


def restart_ids(first_restart: int, n_restarts: int) -> jax.Array:
    """Restart numbers ``first .. first + n - 1``, sharded over all devices when there are several.

    The ids are padded to a multiple of 8 per device (the extra restarts are computed and
    dropped); with d devices they are split along a one-axis mesh, so each device runs its share
    of the restarts; each restart's result is the same on 1 or d devices. Under multi-process
    JAX (``jax.distributed.initialize()`` first), ``jax.devices()`` spans every process and the
    same mesh spreads restarts across them; ``run_restarts`` gathers the results onto every
    process.
    """
    devices = jax.devices()
    ids = np.arange(first_restart, first_restart + padded_count(n_restarts), dtype=np.int32)
    if len(devices) == 1:
        return jax.device_put(ids)
    mesh = jax.sharding.Mesh(np.array(devices), ("restarts",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("restarts"))
    # Each process places only the ids of its own devices (the same call works on one process).
    return jax.make_array_from_callback(ids.shape, sharding, lambda index: ids[index])


def padded_count(n_restarts: int) -> int:
    """Restarts actually run for ``n_restarts``: a multiple of 8 per device.

    The padding keeps every call on the same vectorised code path: XLA's CPU loops round
    differently for batches of a few restarts, which would change the last bits of a restart's
    fitness with the number of restarts beside it.
    """
    return round_up(n_restarts, RESTART_BLOCK * len(jax.devices()))


# The programs this process has run (``run_restarts``), to tell a user when a call compiles.
_RUN_PROGRAMS: set = set()


def _program_key(problem, config, n_particles, n_iters, n_restarts) -> tuple:
    return (problem.spec, config.rules(), n_particles, n_iters, padded_count(n_restarts))


def is_compiled(problem: Problem, config: pso.PSOConfig, n_particles: int, n_iters: int,
                n_restarts: int) -> bool:
    """Whether ``run_restarts`` with these sizes has run in this process (else its next call
    compiles, or loads the program from the persistent compilation cache)."""
    return _program_key(problem, config, n_particles, n_iters, n_restarts) in _RUN_PROGRAMS


def to_host(array: jax.Array) -> np.ndarray:
    """A (possibly multi-process) array as one NumPy array, the same on every process."""
    if array.is_fully_addressable:
        return np.asarray(array)
    from jax.experimental import multihost_utils

    return np.asarray(multihost_utils.process_allgather(array, tiled=True))


def run_restarts(problem: Problem, config: pso.PSOConfig | evosax_adapter.StrategyConfig
                 | custom.CustomConfig,
                 constraint: str, *, n_particles: int, n_iters: int, seed: int,
                 first_restart: int, n_restarts: int, init_particles=None) -> RestartOutcome:
    """The compiled search for restarts ``first_restart ..``, as NumPy arrays."""
    # NumPy arguments: converting them with jax.numpy compiled a small program each, per process
    low, high = (np.asarray(b, dtype=jnp.result_type(float)) for b in problem.bounds())
    given, n_given = np.zeros((n_particles, problem.n_free), low.dtype), 0
    if init_particles is not None:
        n_given = len(init_particles)
        given[:n_given] = init_particles
    data = SearchData(low, high, np.int32(seed), restart_ids(first_restart, n_restarts), given,
                      np.int32(n_given), np.int32(constraint_index(constraint)))
    outcome = compiled_search(problem.spec, problem.device_arrays(), config.params(),
                              config.rules(), data, n_particles=n_particles, n_iters=n_iters,
                              xla_default_level=compiles_best_at_default_level(problem.spec))
    _RUN_PROGRAMS.add(_program_key(problem, config, n_particles, n_iters, n_restarts))
    return RestartOutcome(*(to_host(a)[:n_restarts] for a in outcome))
