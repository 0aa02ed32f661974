"""Gradient polish of a feasible path with optax (``jaxarm.refine``).

PSO ends near an optimum it cannot sharpen: the best paths hug an obstacle, and 20 particles
sample that ridge coarsely. ``refine`` descends a smooth surrogate,

    travelling distance + weight * sum over samples and links of tau * softplus((margin - c) / tau)

where c is a lower bound on the signed clearance of a link at a sample (negative inside an
obstacle; exact for circles, the separating-axis gap for polygons), with any optax optimizer.
Steps are only *accepted* into the returned path when the candidate is collision-free in the
problem's own collision mode (certified if the problem says so) and at least as fit as the best
so far, so the result is never less fit than the input and never collides. The optimizer itself
moves freely on the surrogate; the barrier pulls it back out of obstacles.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxarm import collision as collision_lib
from jaxarm import path
from jaxarm.problem import Problem, _as_params, on_padded_rows, vmapped_evaluate
from jaxarm.programs import jit


class RefineResult(NamedTuple):
    """A polished path."""

    x: np.ndarray  # shape=(..., n_free), the best accepted path
    fitness: np.ndarray  # shape=(...,), its fitness (paper eq. 17), >= the input's
    initial_fitness: np.ndarray  # shape=(...,)
    n_accepted: np.ndarray  # shape=(...,), int: accepted steps that raised the fitness
    history: np.ndarray  # shape=(..., n_steps + 1), best accepted fitness after each step


def surrogate(spec, arrays, x, barrier_weight, margin, temperature):
    """The smooth objective: travelling distance plus a softplus clearance barrier; shape (...,).

    The barrier reads each link's clearance bound (``collision.posture_clearance_bound``: exact
    for circles, the separating-axis gap for polygons) at every sample.
    """
    def add_barrier(total, sample):
        bounds = collision_lib.posture_clearance_bound(arrays.lengths, arrays.world,
                                                       sample.derivatives[0])
        return total + sum(temperature * jax.nn.softplus((margin - c) / temperature)
                           for c in bounds)

    margin = margin + arrays.margin  # the barrier's margin on top of the problem's
    barrier = path.SampleFold(init=jnp.zeros(x.shape[:-1], x.dtype), step=add_barrier,
                              finish=lambda total: total / spec.n_samples, max_order=0)
    distance = path.travelling_distance(arrays.start, arrays.goal, x, spec.degree,
                                        spec.n_samples)
    return distance + barrier_weight * path.run_fold(barrier, arrays.start, arrays.goal, x,
                                                     spec.degree, spec.n_samples)


def _refine_one(spec, arrays, x, optimizer, n_steps, barrier_weight, margin, temperature):
    """Refine one path; its candidates (x itself first) are evaluated at one place in the loop,
    so the program holds one copy of the problem's check. optimizer None: the default."""
    optimizer = DEFAULT_OPTIMIZER if optimizer is None else optimizer
    gradient = jax.grad(lambda z: surrogate(spec, arrays, z, barrier_weight, margin, temperature))

    def body(carry, step):
        params, state, best_x, best_fitness, n_accepted, feasible, initial = carry
        candidate = vmapped_evaluate(spec)(arrays, params)
        first = step == 0  # the input path: it sets the bar, and whether any step may be taken
        feasible = jnp.where(first, candidate.violation == 0, feasible)
        initial = jnp.where(first, candidate.fitness, initial)
        best_fitness = jnp.where(first, candidate.fitness, best_fitness)
        accept = (candidate.violation == 0) & (candidate.fitness >= best_fitness) & feasible
        n_accepted = n_accepted + (accept & (candidate.fitness > best_fitness)).astype(jnp.int32)
        best_x = jnp.where(accept, params, best_x)
        best_fitness = jnp.where(accept, candidate.fitness, best_fitness)
        # the last step's update is never evaluated: it keeps the loop's body in one piece
        grads = gradient(params)
        grads = jnp.where(jnp.isfinite(grads), grads, 0.0)
        updates, state = optimizer.update(grads, state, params)
        params = optax.apply_updates(params, updates)
        return (params, state, best_x, best_fitness, n_accepted, feasible, initial), best_fitness

    zero = jnp.zeros((), x.dtype)
    init = (x, optimizer.init(x), x, zero, jnp.zeros((), jnp.int32), jnp.asarray(False), zero)
    (_, _, best_x, best_fitness, n_accepted, _, initial), history = jax.lax.scan(
        body, init, jnp.arange(n_steps + 1))
    return best_x, best_fitness, initial, n_accepted, history


# One default instance: the optimizer is a static argument, so reusing it reuses the program.
# It is passed as None (a static value with a stable repr: its traced program can be stored).
DEFAULT_OPTIMIZER = optax.adam(0.2)
REFINE_BLOCK = 16  # the smallest padded batch

_compiled_refine = jit(
    jax.vmap(_refine_one, in_axes=(None, None, 0, None, None, None, None, None)),
    static_argnums=(0, 3, 4), storable=True,
)


def refine(problem: Problem, x, n_steps: int = 200, optimizer=None, barrier_weight: float = 1.0,
           margin: float = 0.5, temperature: float = 0.25) -> RefineResult:
    """Polish feasible paths with optax; never returns a less fit or colliding path.

    Args:
      problem: the problem; its collision mode decides what counts as colliding.
      x: feasible free parameters, shape (..., n_free). An infeasible row is returned
        unchanged (no step can be accepted from it).
      n_steps: optimizer steps.
      optimizer: an optax ``GradientTransformation`` (default ``optax.adam(0.2)``); pass the
        same instance again to reuse the compiled program.
      barrier_weight: weight of the clearance barrier (per sample, in the distance's units).
      margin, temperature: the barrier's clearance margin (cm, on top of ``problem.margin``)
        and softness (cm).

    Returns:
      ``RefineResult`` whose fields have x's leading shape (...) (``x``: x's shape;
      ``history``: (..., n_steps + 1)).

    Example:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> polished = refine(problem, [113.0533, -42.3741, -10.0300])
      >>> bool(polished.fitness > 0.1476)
      True
    """
    x = _as_params(problem, x)
    leading = x.shape[:-1]
    if x.size == 0:  # nothing to polish (e.g. no feasible restart): no kernel call
        zeros = np.zeros(leading, np.asarray(x).dtype)
        return RefineResult(np.asarray(x), zeros, zeros, np.zeros(leading, np.int32),
                            np.zeros(leading + (int(n_steps) + 1,), zeros.dtype))
    optimizer = None if optimizer is DEFAULT_OPTIMIZER else optimizer
    # Padded to a few batch sizes (>= 16 rows): a few compiled programs per problem shape,
    # whatever the batch size, in one vectorised call.
    out = on_padded_rows(
        lambda rows: _compiled_refine(problem.spec, problem.arrays, rows, optimizer,
                                      int(n_steps), barrier_weight, margin, temperature),
        x, smallest=REFINE_BLOCK)
    return RefineResult(*(np.asarray(a) for a in out))
