"""Polynomial joint paths with rest-to-rest boundary conditions (paper eqs. 6-11, 5).

Each joint follows ``theta(r) = sum_n a_n r^n`` for normalised time ``r in [0, 1]``, with
``theta(0) = theta_i``, ``theta(1) = theta_f`` and zero first and second derivatives at both
ends. For degree d those six conditions fix ``a_0 .. a_5``; the ``d - 5`` coefficients
``a_6 .. a_d`` of each joint are free. Because the conditions are linear, every path is

    theta(r) = theta_i + (theta_f - theta_i) h(r) + sum_{p=6..d} a_p g_p(r),

with the quintic ``h(r) = 10 r^3 - 15 r^4 + 6 r^5`` and ``g_p(r) = r^p + (terms of degree 3-5)``
vanishing with two derivatives at both ends (``g_6(r) = r^3 (r - 1)^3``). For d = 6 this is
exactly the paper's eq. 10. Evaluating through the basis keeps float32 well conditioned: the
coefficients themselves can reach hundreds while the angles stay small.

Free parameters are ordered by power, then joint: ``x = [a6_1 .. a6_J, a7_1 .. a7_J, ...]``,
so degree 6 gives the paper's ``[a61 a62 a63]``.

Per-path quantities along the samples of r (travelling distance here, the collision checks in
``collision``) are ``SampleFold``s that ``run_fold`` walks one sample at a time.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._validate import positive_int
from jaxarm.choices import MAX_DEGREE, MIN_DEGREE


def n_free_per_joint(degree: int) -> int:
    """Free coefficients per joint, ``degree - 5``."""
    return degree - 5


def basis_coefficients(degree: int, order: int = 0) -> np.ndarray:
    """Polynomial coefficients of the ``order``-th derivative of the basis ``[h, g_6, ..., g_d]``.

    Returns:
      Array of shape (degree - 4, degree + 1), ascending powers (zero-padded at the top for
      derivatives); row 0 is ``h``.
    """
    # a3, a4, a5 solve [[1,1,1],[3,4,5],[6,12,20]] a = b for the end conditions at r = 1;
    # the inverse matrix below is exact.
    inverse = np.array([[10.0, -4.0, 0.5], [-15.0, 7.0, -1.0], [6.0, -3.0, 0.5]])
    rows = []
    h = np.zeros(degree + 1)
    h[3:6] = inverse @ np.array([1.0, 0.0, 0.0])
    rows.append(h)
    for power in range(MIN_DEGREE, degree + 1):
        g = np.zeros(degree + 1)
        g[power] = 1.0
        g[3:6] = inverse @ -np.array([1.0, power, power * (power - 1)])
        rows.append(g)
    coefficients = np.stack(rows)
    for _ in range(order):
        coefficients = np.pad(coefficients[:, 1:] * np.arange(1, degree + 1), ((0, 0), (0, 1)))
    return coefficients


def powers(r, degree: int):
    """``r^0 .. r^degree`` by repeated multiplication (exact for integer exponents, no pow).

    Args:
      r: shape (..., n_r); NumPy in float64 NumPy, JAX in JAX.

    Returns:
      Array of shape (..., n_r, degree + 1).
    """
    xp = np if isinstance(r, np.ndarray) else jnp
    columns = [xp.ones_like(r), r]
    for _ in range(degree - 1):
        columns.append(columns[-1] * r)
    return xp.stack(columns[: degree + 1], axis=-1)


def basis_values(degree: int, r, order: int = 0, r_powers=None):
    """Values of the ``order``-th derivative of ``[h, g_6, ..., g_d]`` at ``r``.

    Args:
      degree: polynomial degree d >= 6.
      r: normalised times, shape (n_r,) or (..., n_r). A NumPy array (or list) is evaluated
        in float64 NumPy, a compile-time constant under jit; a JAX array in JAX.
      order: derivative order.
      r_powers: ``powers(r, degree)``, to share between several orders.

    Returns:
      Array of shape r.shape + (degree - 4,).
    """
    if not isinstance(r, jax.Array):
        r = np.asarray(r, dtype=np.float64)
    if r_powers is None:
        r_powers = powers(r, degree)
    coefficients = basis_coefficients(degree, order)
    if isinstance(r_powers, np.ndarray):
        return r_powers @ coefficients.T
    # Unrolled over the powers: elementwise work fuses, a contraction over 7 terms does not.
    coefficients = jnp.asarray(coefficients, dtype=r_powers.dtype)
    leading = (1,) * (r_powers.ndim - 1)  # the same rank on both sides
    return sum(r_powers[..., k, None] * coefficients[:, k].reshape(leading + (-1,))
               for k in range(degree + 1))


def raise_degree(x, n_joints: int, degree: int):
    """The same paths as free parameters of a higher degree (zeros for the new powers).

    Args:
      x: free parameters of some degree d, shape (..., n_joints * (d - 5)).
      n_joints: number of joints.
      degree: the new degree, >= d and at most ``MAX_DEGREE``.

    Returns:
      Array of shape (..., n_joints * (degree - 5)), describing identical joint paths.
    """
    positive_int("degree", degree, minimum=MIN_DEGREE, maximum=MAX_DEGREE)
    positive_int("n_joints", n_joints)
    x = np.asarray(x)
    extra = n_joints * n_free_per_joint(degree) - x.shape[-1]
    if extra < 0 or x.shape[-1] % n_joints:
        raise ValueError(f"cannot raise {x.shape[-1]} free parameters of {n_joints} joints to "
                         f"degree {degree}")
    return np.concatenate([x, np.zeros(x.shape[:-1] + (extra,), x.dtype)], axis=-1)


def free_by_joint(x, n_joints: int):
    """Reshape free parameters (..., n_free) to (..., degree - 5, n_joints)."""
    # not -1: reshaping an empty batch with -1 divides by zero
    return x.reshape(x.shape[:-1] + (x.shape[-1] // n_joints, n_joints))


def joint_angle_list(start, goal, x, basis, order: int = 0, per_path: bool = False) -> list:
    """Joint angles (or a derivative) at the times a basis was evaluated at, one array per joint.

    Args:
      start, goal: joint angles at r = 0 and r = 1, shape (n_joints,).
      x: free parameters, shape (..., n_free).
      basis: ``basis_values(degree, r, order)``: shape (n_r, degree - 4) shared by the batch,
        (..., n_r, degree - 4) with the batch shape of ``x``, or (degree - 4,) for one time.
        With ``per_path``, shape (..., degree - 4): one time per path.
      order: the derivative order the basis was evaluated with (the constant ``start`` term
        only appears for order 0).

    Returns:
      A list of n_joints arrays of shape (..., n_r), or (...,) for one time.
    """
    start = jnp.asarray(start, dtype=x.dtype)
    goal = jnp.asarray(goal, dtype=x.dtype)
    basis = jnp.asarray(basis, dtype=x.dtype)
    free = free_by_joint(x, start.shape[-1])  # (..., degree - 5, n_joints)
    time_axis = (None,) if basis.ndim > 1 and not per_path else ()  # broadcast along times
    lead = x.ndim - basis.ndim + len(time_axis)
    if lead > 0:  # a basis shared by the batch: its leading axes made explicit
        basis = basis.reshape((1,) * lead + basis.shape)
    # Unrolled over joints and free powers: elementwise, so it fuses with what follows
    # (a batched contraction over such small axes compiles to a slow loop on CPU).
    angles = []
    for k in range(start.shape[-1]):
        theta = basis[..., 0] * (goal[k] - start[k])
        for m in range(free.shape[-2]):
            theta = theta + basis[..., m + 1] * free[(..., m, k) + time_axis]
        angles.append(theta + start[k] if order == 0 else theta)
    return angles


def joint_angle_array(start, goal, x, basis, order: int = 0):
    """``joint_angle_list`` stacked: shape (..., n_r, n_joints)."""
    return jnp.stack(joint_angle_list(start, goal, x, basis, order), axis=-1)


def polynomial_coefficients(start, goal, x, degree: int):
    """Full polynomial coefficients ``a_0 .. a_d`` of each joint (paper eq. 10 for d = 6).

    Args:
      start, goal: joint angles, shape (n_joints,).
      x: free parameters, shape (..., n_free); a NumPy array is computed in NumPy (float64
        for float64 input), a JAX array in JAX.
      degree: polynomial degree.

    Returns:
      Array of shape (..., n_joints, degree + 1), ascending powers.
    """
    xp = np if isinstance(x, np.ndarray) else jnp
    start = xp.asarray(start, dtype=x.dtype)
    goal = xp.asarray(goal, dtype=x.dtype)
    basis = xp.asarray(basis_coefficients(degree), dtype=x.dtype)
    free = free_by_joint(x, start.shape[-1])
    constant = xp.asarray(np.eye(1, degree + 1)[0], dtype=x.dtype)  # a_0 only
    return (xp.einsum("...mj,mn->...jn", free, basis[1:]) + (goal - start)[:, None] * basis[0]
            + start[:, None] * constant)


def simpson_weights(n_samples: int) -> np.ndarray:
    """Composite Simpson weights over ``n_samples`` (odd) equally spaced points of [0, 1]."""
    weights = np.ones(n_samples)
    weights[1:-1:2] = 4.0
    weights[2:-1:2] = 2.0
    return weights / (3.0 * (n_samples - 1))


class Sample(NamedTuple):
    """One of the n equally spaced times of r, as ``run_fold`` hands it to a fold's step."""

    index: jax.Array  # shape=(), int32: s in 0 .. n_samples - 1, at r = s / (n_samples - 1)
    weight: jax.Array  # shape=(), the Simpson weight of the sample
    derivatives: tuple  # derivatives[order][joint]: d^order theta / dr^order, shape (...,)


class SampleFold(NamedTuple):
    """A per-path quantity accumulated along the samples of r: ``finish`` of the carry after
    ``carry = step(carry, sample)`` for every sample in order, starting from ``init``."""

    init: Any  # pytree of arrays: the carry before the first sample
    step: Callable  # (carry, Sample) -> carry
    finish: Callable  # carry -> result
    max_order: int  # highest derivative order ``step`` reads


def run_fold(fold: SampleFold, start, goal, x, degree: int, n_samples: int):
    """Run a fold as one ``lax.scan`` over the samples of r.

    One sample at a time keeps the working set to a few arrays of the batch size, which stay
    in cache; materialising (batch, n_samples) intermediates instead makes the kernel
    memory-bound on CPU.

    Args:
      fold: the ``SampleFold``.
      start, goal: joint angles, shape (n_joints,).
      x: free parameters, shape (..., n_free).
      degree, n_samples: static sizes.

    Returns:
      ``fold.finish`` of the last carry.
    """
    r = np.linspace(0.0, 1.0, n_samples)
    basis = np.stack([basis_values(degree, r, order) for order in range(fold.max_order + 1)],
                     axis=1)
    constants = (np.arange(n_samples, dtype=np.int32),
                 jnp.asarray(simpson_weights(n_samples), x.dtype), jnp.asarray(basis, x.dtype))

    def body(carry, constants_row):
        index, weight, basis_row = constants_row  # basis_row: (max_order + 1, degree - 4)
        derivatives = tuple(joint_angle_list(start, goal, x, basis_row[order], order)
                            for order in range(fold.max_order + 1))
        return fold.step(carry, Sample(index, weight, derivatives)), None

    carry, _ = jax.lax.scan(body, fold.init, constants)
    return fold.finish(carry)


def sample_values(value: Callable, start, goal, x, degree: int, n_samples: int,
                  max_order: int = 0):
    """``value(sample)`` (a ``Sample`` with derivatives up to ``max_order``, each of shape
    ``x.shape[:-1]``; an array or a pytree of them) at every sample, as one ``lax.scan``:
    each array with a leading axis of n_samples.

    Each value is written into the result one step late: written in the step that computes
    it, XLA's CPU backend fused the computation into the write, which slowed stage 0 of the
    certified check (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Windows
    screened by their swing").
    """
    probe = Sample(jnp.int32(0), jnp.zeros((), x.dtype),
                   tuple((jnp.zeros(x.shape[:-1], x.dtype),) * start.shape[-1]
                         for _ in range(max_order + 1)))
    shapes = jax.eval_shape(value, probe)

    def write(values, row, new):
        return jax.tree.map(lambda v, n: jax.lax.dynamic_update_index_in_dim(v, n, row, 0),
                            values, new)

    def step(carry, sample):
        previous, values = carry
        row = jnp.maximum(sample.index - 1, 0)  # sample 0's row is written again at sample 1
        return value(sample), write(values, row, previous)

    def finish(carry):
        last, values = carry
        return write(values, n_samples - 1, last)

    init = (jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes),
            jax.tree.map(lambda s: jnp.zeros((n_samples,) + s.shape, s.dtype), shapes))
    return run_fold(SampleFold(init=init, step=step, finish=finish, max_order=max_order),
                    start, goal, x, degree, n_samples)


def arc_length_rate(velocity: list):
    """``sum_k sqrt(1 + theta_k'(r)^2)``, the integrand of eq. 5 summed over joints.

    Args:
      velocity: per-joint ``d theta / dr``, each of shape (...,).

    Returns:
      Array of shape (...,).
    """
    return sum(jnp.sqrt(1.0 + v * v) for v in velocity)


def distance_fold(x) -> SampleFold:
    """Joint angle travelling distance summed over joints (paper eq. 5 by Simpson's rule),
    as a fold: ``sum_k integral_0^1 sqrt(1 + theta_k'(r)^2) dr``, shape (...,).

    Args:
      x: free parameters, shape (..., n_free) (for the batch shape and dtype).
    """
    return SampleFold(
        init=jnp.zeros(x.shape[:-1], x.dtype),
        step=lambda total, sample: total + sample.weight * arc_length_rate(sample.derivatives[1]),
        finish=lambda total: total,
        max_order=1,
    )


def simpson_distance(start, goal, x, degree: int, n_samples: int):
    """``distance_fold`` on its own: the travelling distance of the paths ``x`` by Simpson's
    rule over ``n_samples`` points (``jaxarm.travelling_distance`` computes it for a problem).

    Args:
      start, goal: joint angles, shape (n_joints,).
      x: free parameters, shape (..., n_free).
      degree, n_samples: the path's degree and the (odd) number of Simpson points.

    Returns:
      Array of shape (...,).
    """
    return run_fold(distance_fold(x), start, goal, x, degree, n_samples)
