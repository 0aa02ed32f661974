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

import functools
import operator
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxarm._compile.jit import jit
from jaxarm._compile.padding import on_padded_rows
from jaxarm.checks.evaluate import link_clearances, vmapped_evaluate
from jaxarm.model import path
from jaxarm.model.arm import link_endpoints
from jaxarm.model.problem import Problem, as_params


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
    for circles, the separating-axis gap for polygons) at every sample. All samples are
    computed at once, as (..., n_samples) arrays: refine's batches are small, and the gradient
    of a ``lax.scan`` over the samples (``path.run_fold``) made refine slower
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Refine takes all samples at
    once, in power-of-two batches").
    """
    angle, rate = _angles_and_rates(arrays, x, _sample_bases(spec, x.dtype))
    return _surrogate_at_samples(spec, arrays, angle, rate, barrier_weight, margin, temperature)


def surrogate_gradient(spec, arrays, x, barrier_weight, margin, temperature, needed=None):
    """``grad(surrogate)`` with respect to x, shape (..., n_free).

    The chain rule through the joint angles is written out, its sums over the samples taken in
    order: autodiff's own sums (the transpose of broadcasting x along the samples) are split
    differently for different batch sizes, and a refined row's last bits then depended on how
    many rows were refined with it.

    ``needed``: optionally a bool scalar (may be traced), False when the gradient goes unused
    (its values are then meaningless): the links' end points are computed in a branch on it
    (``_surrogate_at_samples``).
    """
    bases = _sample_bases(spec, x.dtype)
    angle, rate = _angles_and_rates(arrays, x, bases)

    def total(angle, rate):
        return jnp.sum(_surrogate_at_samples(spec, arrays, angle, rate, barrier_weight, margin,
                                             temperature, needed))

    by_angle, by_rate = jax.grad(total, argnums=(0, 1))(angle, rate)  # per joint (..., n_samples)
    n_joints = len(angle)
    lead = (1,) * (by_angle[0].ndim - 1)  # the samples' basis values, broadcast over the batch
    bases = [basis.reshape(lead + basis.shape) for basis in bases]
    # x[..., m * n_joints + k] is joint k's coefficient of the (m + 1)-th free basis function
    return jnp.stack([_sum_over_samples(bases[0][..., m + 1] * by_angle[k]
                                        + bases[1][..., m + 1] * by_rate[k])
                      for m in range(x.shape[-1] // n_joints) for k in range(n_joints)], axis=-1)


def _sample_bases(spec, dtype) -> list:
    """``path.basis_values`` of orders 0 and 1 at the samples, each (n_samples, degree - 4)."""
    r = np.linspace(0.0, 1.0, spec.n_samples)
    return [jnp.asarray(path.basis_values(spec.degree, r, order), dtype) for order in (0, 1)]


def _angles_and_rates(arrays, x, bases):
    """Joint angles and their rates d theta / dr at the samples (``_sample_bases``): two lists
    of n_joints arrays of shape (..., n_samples)."""
    return tuple(path.joint_angle_list(arrays.start, arrays.goal, x, basis, order)
                 for order, basis in enumerate(bases))


def _surrogate_at_samples(spec, arrays, angle, rate, barrier_weight, margin, temperature,
                          needed=None):
    """The surrogate from the joint angles and rates at the samples (``_angles_and_rates``).

    With ``needed`` (``surrogate_gradient``) the links' end points come from a branch on it:
    XLA's CPU backend otherwise copies their sines and cosines into each of the clearance
    bounds' fusions, in the gradient too (``benchmarks/RESULTS.md``, *Decisions and negative
    results*, "The piece test in two branches").
    """
    speed = path.arc_length_rate(rate)  # (..., n_samples)
    weights = jnp.asarray(path.simpson_weights(spec.n_samples), speed.dtype)
    distance = _sum_over_samples(weights.reshape((1,) * (speed.ndim - 1) + weights.shape)
                                 * speed)  # paper eq. 5
    margin = margin + arrays.margin  # the barrier's margin on top of the problem's
    if needed is None:
        links = link_endpoints(arrays.lengths, angle)
    else:
        links = jax.lax.cond(needed, lambda a: link_endpoints(arrays.lengths, a),
                             lambda a: [(jnp.zeros_like(a[0]),) * 4] * len(a), angle)
    bounds = link_clearances(arrays.lengths, arrays.world, links)
    barrier = sum(temperature * jax.nn.softplus((margin - c) / temperature) for c in bounds)
    return distance + barrier_weight * _sum_over_samples(barrier) / spec.n_samples


def _sum_over_samples(values):
    """(..., n_samples) -> (...,), added sample by sample in order: a reduction over the last
    axis is split differently for different batch sizes."""
    pieces = jax.lax.split(values, (1,) * values.shape[-1], axis=values.ndim - 1)
    return functools.reduce(operator.add, pieces)[..., 0]


def _refine_rows(spec, arrays, x, optimizer, n_steps, barrier_weight, margin, temperature):
    """Refine paths x (B, n_free), each row on its own; its candidates (x itself first) are
    evaluated at one place in the loop, so the program holds one copy of the problem's check.
    optimizer None: the default.

    The loop runs on the whole batch: only the optimizer is mapped over the rows (so that one
    with a norm or other reduction sees one row's parameters). A ``vmap`` of a one-row loop
    gave the same bits but traced the loop's body twice more (JAX's scan batching rule)
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Loops traced once: refine
    and the restarts").
    """
    optimizer = DEFAULT_OPTIMIZER if optimizer is None else optimizer
    update = jax.vmap(optimizer.update)

    def gradient(z, needed):
        return surrogate_gradient(spec, arrays, z, barrier_weight, margin, temperature, needed)

    def body(carry, step):
        params, state, best_x, best_fitness, n_accepted, feasible, initial = carry
        candidate = vmapped_evaluate(spec)(arrays, params)
        first = step == 0  # the input path: it sets the bar, and whether any step may be taken
        feasible = jnp.where(first, candidate.violation == 0, feasible)
        initial = jnp.where(first, candidate.fitness, initial)
        best_fitness = jnp.where(first, candidate.fitness, best_fitness)
        accept = (candidate.violation == 0) & (candidate.fitness >= best_fitness) & feasible
        n_accepted = n_accepted + (accept & (candidate.fitness > best_fitness)).astype(jnp.int32)
        best_x = jnp.where(accept[:, None], params, best_x)
        best_fitness = jnp.where(accept, candidate.fitness, best_fitness)
        # the last step's update is never evaluated: it keeps the loop's body in one piece
        grads = gradient(params, feasible.any())  # no feasible row: no step is accepted
        grads = jnp.where(jnp.isfinite(grads), grads, 0.0)
        updates, state = update(grads, state, params)
        params = optax.apply_updates(params, updates)
        return (params, state, best_x, best_fitness, n_accepted, feasible, initial), best_fitness

    rows = x.shape[:1]
    zero = jnp.zeros(rows, x.dtype)
    init = (x, jax.vmap(optimizer.init)(x), x, zero, jnp.zeros(rows, jnp.int32),
            jnp.zeros(rows, bool), zero)
    (_, _, best_x, best_fitness, n_accepted, _, initial), history = jax.lax.scan(
        body, init, jnp.arange(n_steps + 1))
    return best_x, best_fitness, initial, n_accepted, history.T


# One default instance: the optimizer is a static argument, so reusing it reuses the program.
# It is passed as None (a static value with a stable repr: its traced program can be stored).
DEFAULT_OPTIMIZER = optax.adam(0.2)
REFINE_BLOCK = 16  # the smallest padded batch

_compiled_refine = jit(_refine_rows, static_argnums=(0, 3, 4), storable=True,
                       label="refine")


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
      margin: the barrier's clearance margin (cm, on top of ``problem.margin``).
      temperature: the barrier's softness (cm).

    Returns:
      ``RefineResult`` whose fields have x's leading shape (...) (``x``: x's shape;
      ``history``: (..., n_steps + 1)).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> polished = jaxarm.refine(problem, [113.0533, -42.3741, -10.0300])
      >>> bool(polished.fitness > 0.1476)
      True
    """
    x = as_params(problem, x)
    leading = x.shape[:-1]
    if x.size == 0:  # nothing to polish (e.g. no feasible restart): no kernel call
        zeros = np.zeros(leading, np.asarray(x).dtype)
        return RefineResult(np.asarray(x), zeros, zeros, np.zeros(leading, np.int32),
                            np.zeros(leading + (int(n_steps) + 1,), zeros.dtype))
    optimizer = None if optimizer is DEFAULT_OPTIMIZER else optimizer
    # Padded to a few batch sizes (>= 16 rows): a few compiled programs per problem shape,
    # whatever the batch size, in one vectorised call.
    out = on_padded_rows(
        lambda rows: _compiled_refine(problem.spec, problem.device_arrays(), rows, optimizer,
                                      int(n_steps), barrier_weight, margin, temperature),
        x, smallest=REFINE_BLOCK)
    return RefineResult(*(np.asarray(a) for a in out))
