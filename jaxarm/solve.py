"""``solve``: many independent PSO restarts in one compiled program.

Restarts are vmapped (and sharded over all devices when there are several), iterations run in
``lax.scan``. Restart i draws everything from
``fold_in(key(seed), i)`` (and iteration t from ``fold_in`` of that with t), so its result does not
depend on how many restarts run beside it or how they are chunked. The compiled program is
specialised only on sizes and modes (``ProblemSpec``, particles, iterations, restarts, the
constraint rule and the config's tie-breaking and beta mode); angles, obstacles, PSO
coefficients, the init range and the seed are data, so a new scenario or preset reuses it.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import pso
from jaxarm._validate import positive_int
from jaxarm.problem import Problem, ProblemArrays, ProblemSpec, certify, vmapped_evaluate


class Result(NamedTuple):
    """What ``solve`` found: the best restart, every restart, and how it was produced."""

    best_x: np.ndarray  # shape=(n_free,), the best restart's global best
    best_fitness: float  # paper eq. 17 fitness of best_x (0 if infeasible)
    feasible: bool  # best_x is collision-free in the problem's collision mode
    escape_iter: int  # the best restart's escape iteration, -1 if it never escaped
    history: np.ndarray  # shape=(n_iters + 1,), the best restart's global-best fitness
    restart_best_x: np.ndarray  # shape=(n_restarts, n_free)
    restart_best_fitness: np.ndarray  # shape=(n_restarts,)
    restart_best_violation: np.ndarray  # shape=(n_restarts,), 0 iff feasible
    restart_escape_iter: np.ndarray  # shape=(n_restarts,), int, -1 when never escaped
    restart_escape_x: np.ndarray  # shape=(n_restarts, n_free), global best at escape, NaN if never
    restart_history: np.ndarray  # shape=(n_restarts, n_iters + 1)
    certified: bool  # best_x proved free for every r by ``jaxarm.certify``
    pso_best_fitness: float  # best_fitness before refinement (equal when refine=False)
    method: str  # preset name or "custom"
    config: pso.PSOConfig
    constraint: str
    collision: str  # the collision mode the search used
    seed: int
    seconds: float  # wall time of the call, compilation included

    @property
    def n_restarts(self) -> int:
        return int(self.restart_best_fitness.shape[0])

    def summary(self) -> str:
        """A few human-readable lines."""
        escaped = int(np.sum(self.restart_escape_iter >= 0))
        return "\n".join([
            f"method {self.method} ({self.config.velocity_rule}), constraint {self.constraint}, "
            f"{self.collision} collision check, seed {self.seed}",
            f"best a   {np.array2string(self.best_x, precision=4, separator=', ')}",
            f"fitness  {self.best_fitness:.5g}  feasible {self.feasible}  "
            f"certified {self.certified}",
            *([f"WARNING  feasible only at the {self.collision} check's samples: the motion is "
               "not certified collision-free between them"]
              if self.feasible and not self.certified else []),
            f"escape   iteration {self.escape_iter} (best restart); "
            f"{escaped}/{self.n_restarts} restarts escaped",
            f"time     {self.seconds:.2f} s",
        ])


class RestartOutcome(NamedTuple):
    """Per-restart arrays returned by the compiled search."""

    best_x: jax.Array  # shape=(n_restarts, n_free)
    best_fitness: jax.Array  # shape=(n_restarts,)
    best_violation: jax.Array  # shape=(n_restarts,)
    escape_iter: jax.Array  # shape=(n_restarts,), int32
    escape_x: jax.Array  # shape=(n_restarts, n_free), global best at escape; NaN if never
    history: jax.Array  # shape=(n_restarts, n_iters + 1)


def _one_restart(key, spec, arrays, numbers, structure, low, high, init_particles,
                 n_particles, n_iters, constraint):
    def score_fn(x):
        evaluation = vmapped_evaluate(spec)(arrays, x)
        return pso.constraint_score(constraint, evaluation.fitness, evaluation.violation)

    state, info = pso.init(jax.random.fold_in(key, 0), score_fn, numbers, structure, low, high,
                           n_particles, init_particles)
    nan = jnp.full(low.shape, jnp.nan, low.dtype)
    escape_x = jnp.where(state.escape_iter == 0, state.best_position[state.global_index], nan)

    def body(carry, iteration):
        state, escape_x = carry
        state, info = pso.step(jax.random.fold_in(key, iteration), state, score_fn, numbers,
                               structure, low, high, n_iters)
        escaped_now = state.escape_iter == iteration
        escape_x = jnp.where(escaped_now, state.best_position[state.global_index], escape_x)
        return (state, escape_x), info.global_fitness

    (state, escape_x), history = jax.lax.scan(body, (state, escape_x),
                                              jnp.arange(1, n_iters + 1))
    best_x = state.best_position[state.global_index]
    final = vmapped_evaluate(spec)(arrays, best_x)
    return RestartOutcome(
        best_x=best_x,
        best_fitness=final.fitness,
        best_violation=final.violation,
        escape_iter=state.escape_iter,
        escape_x=escape_x,
        history=jnp.concatenate([info.global_fitness[None], history]),
    )


def search(spec: ProblemSpec, arrays: ProblemArrays, numbers, structure, low, high, seed,
           restart_ids, init_particles, *, n_particles: int, n_iters: int,
           constraint: str) -> RestartOutcome:
    """Run the restarts numbered ``restart_ids`` (pure; jit below).

    Args:
      spec: static problem part; arrays: its data.
      numbers, structure: ``PSOConfig.numbers()`` and ``.structure()``.
      low, high: init range, shape (n_free,).
      seed: int32 scalar.
      restart_ids: int32, shape (n_restarts,); restart i uses ``fold_in(key(seed), i)``.
      init_particles: None or shape (n_given, n_free).

    Returns:
      ``RestartOutcome`` with leading axis n_restarts.
    """
    keys = jax.vmap(lambda i: jax.random.fold_in(jax.random.key(seed), i))(restart_ids)
    run = lambda key: _one_restart(key, spec, arrays, numbers, structure, low, high,  # noqa: E731
                                   init_particles, n_particles, n_iters, constraint)
    return jax.vmap(run)(keys)


compiled_search = jax.jit(
    search, static_argnames=("spec", "structure", "n_particles", "n_iters", "constraint")
)


RESTART_BLOCK = 8


def restart_ids(first_restart: int, n_restarts: int) -> jax.Array:
    """Restart numbers ``first .. first + n - 1``, sharded over all devices when there are several.

    The ids are padded to a multiple of 8 per device (the extra restarts are computed and
    dropped); with d devices they are split along a one-axis mesh, so each device runs its share of the restarts;
    each restart's result is the same on 1 or d devices. Under multi-host JAX
    (``jax.distributed.initialize()`` first), ``jax.devices()`` spans every host and the same
    mesh spreads restarts across them.
    """
    devices = jax.devices()
    # Padding to a multiple of 8 restarts per device keeps every call on the same vectorised
    # code path: XLA's CPU loops round differently for batches of a few restarts, which would
    # change the last bits of a restart's fitness with the number of restarts beside it.
    block = RESTART_BLOCK * len(devices)
    n_padded = -(-n_restarts // block) * block
    ids = np.arange(first_restart, first_restart + n_padded, dtype=np.int32)
    if len(devices) == 1:
        return jnp.asarray(ids)
    mesh = jax.sharding.Mesh(np.array(devices), ("restarts",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("restarts"))
    return jax.device_put(ids, sharding)


def method_name(method) -> str:
    return method if isinstance(method, str) else "custom"


def solve(problem: Problem, method: str | pso.PSOConfig = "A", *, n_particles: int = 20,
          n_iters: int = 100, n_restarts: int = 1, seed: int = 0, constraint: str = "death",
          init_particles=None, refine: bool | str = False) -> Result:
    """Search the problem's free coefficients with PSO, ``n_restarts`` independent swarms at once.

    Args:
      problem: the problem.
      method: "A", "B", "C" (the paper's Table 2 presets) or a ``PSOConfig``.
      n_particles: swarm size (paper: 20).
      n_iters: PSO updates (paper: 100); iteration 0 is the initial swarm.
      n_restarts: independent swarms, restart i seeded by ``fold_in(key(seed), i)``.
      seed: integer seed.
      constraint: "death" (paper eq. 17) or "feasibility" (feasibility rules on the violation).
      init_particles: optional particles, shape (n_given, n_free), put at the start of every
        restart's initial swarm (paper Table 6).
      refine: polish with ``jaxarm.refine`` after PSO: False, True (the best restart) or
        "all" (every feasible restart, then the best is chosen again). Never worse.

    Returns:
      ``Result``.

    Example:
      >>> result = jaxarm.solve(jaxarm.load_scenario("paper-case-2"), constraint="feasibility")
      >>> result.feasible
      True
    """
    began = time.perf_counter()
    config = pso.resolve(method)
    if constraint not in pso.CONSTRAINTS:
        raise ValueError(f"constraint must be one of {pso.CONSTRAINTS}, got {constraint!r}")
    n_particles = positive_int("n_particles", n_particles)
    n_iters = positive_int("n_iters", n_iters)
    n_restarts = positive_int("n_restarts", n_restarts)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not (
        0 <= seed < 2**31
    ):
        raise ValueError(f"seed must be an integer in [0, 2**31), got {seed!r}")
    if refine not in (False, True, "all"):
        raise ValueError(f"refine must be False, True or 'all', got {refine!r}")
    given = _check_init_particles(problem, init_particles, n_particles)
    outcome = run_restarts(problem, config, constraint, n_particles, n_iters, seed, 0,
                           n_restarts, given)
    pso_best = float(outcome.best_fitness[_best_restart(outcome.best_fitness,
                                                        outcome.best_violation)])
    if refine:
        outcome = _refined(problem, outcome, every=refine == "all")
    return _result(problem, method, config, constraint, seed, outcome, pso_best, began)


def _refined(problem, outcome: RestartOutcome, every: bool) -> RestartOutcome:
    """The outcome with the best (or every) feasible restart polished by ``refine``."""
    from jaxarm.refine import refine

    rows = (np.arange(len(outcome.best_fitness)) if every else
            np.array([_best_restart(outcome.best_fitness, outcome.best_violation)]))
    rows = rows[outcome.best_violation[rows] == 0]
    if rows.size == 0:
        return outcome
    polished = refine(problem, outcome.best_x[rows])
    # Kept only where strictly fitter than the PSO's own evaluation: the same x evaluated by
    # another compiled program can differ in the last bit, and "never worse" must hold here.
    better = polished.fitness > outcome.best_fitness[rows]
    best_x, best_fitness = outcome.best_x.copy(), outcome.best_fitness.copy()
    best_x[rows[better]], best_fitness[rows[better]] = polished.x[better], polished.fitness[better]
    return outcome._replace(best_x=best_x, best_fitness=best_fitness)


def run_restarts(problem, config, constraint, n_particles, n_iters, seed, first_restart,
                 n_restarts, init_particles=None) -> RestartOutcome:
    """The compiled search for restarts ``first_restart ..``, as NumPy arrays (for studies)."""
    low, high = (jnp.asarray(b, dtype=jnp.result_type(float)) for b in problem.bounds())
    outcome = compiled_search(
        problem.spec, problem.arrays, config.numbers(), config.structure(), low, high,
        jnp.int32(seed), restart_ids(first_restart, n_restarts), init_particles,
        n_particles=n_particles, n_iters=n_iters, constraint=constraint,
    )
    return RestartOutcome(*(np.asarray(a)[:n_restarts] for a in outcome))


def _check_init_particles(problem, init_particles, n_particles):
    if init_particles is None:
        return None
    given = np.asarray(init_particles, dtype=np.float64)
    if given.ndim == 1:
        given = given[None]
    if given.ndim != 2 or given.shape[1] != problem.n_free or given.shape[0] > n_particles:
        raise ValueError(
            f"init_particles must have shape (n_given <= {n_particles}, {problem.n_free}), "
            f"got {np.shape(init_particles)}"
        )
    if not np.all(np.isfinite(given)):
        raise ValueError(f"init_particles must be finite, got {init_particles!r}")
    return jnp.asarray(given, dtype=jnp.result_type(float))


def _best_restart(fitness, violation) -> int:
    """Highest fitness among feasible restarts, else least violation; first index on ties."""
    feasible = violation == 0
    score = np.where(feasible, fitness, -violation)
    return int(np.argmax(score))


def _result(problem, method, config, constraint, seed, outcome: RestartOutcome, pso_best, began
            ) -> Result:
    best = _best_restart(outcome.best_fitness, outcome.best_violation)
    best_x = outcome.best_x[best]
    feasible = bool(outcome.best_violation[best] == 0)
    certified = feasible and (problem.collision == "certified"
                              or bool(certify(problem, best_x).free))
    return Result(
        best_x=best_x,
        best_fitness=float(outcome.best_fitness[best]),
        feasible=feasible,
        escape_iter=int(outcome.escape_iter[best]),
        history=outcome.history[best],
        restart_best_x=outcome.best_x,
        restart_best_fitness=outcome.best_fitness,
        restart_best_violation=outcome.best_violation,
        restart_escape_iter=outcome.escape_iter,
        restart_escape_x=outcome.escape_x,
        restart_history=outcome.history,
        certified=certified,
        pso_best_fitness=pso_best,
        method=method_name(method),
        config=config,
        constraint=constraint,
        collision=problem.collision,
        seed=int(seed),
        seconds=time.perf_counter() - began,
    )
