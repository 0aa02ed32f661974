"""Collision checks of a whole motion: the paper's sampled check and a certified continuous one.

Both are folds along the path, one sample of r at a time (``path.run_fold``), so the working
set stays a few arrays of the batch shape.

``sampled`` (the paper's Fig. 8): the links are checked against every obstacle at the ``n``
equally spaced samples of r. A thin obstacle can slip between two samples.

``certified``: a guarantee that every link is collision-free for every r in [0, 1].

Proof sketch. A point p of link k is ``p = sum_{i<k} l_i u(phi_i) + t l_k u(phi_k)`` with
``phi_i = theta_1 + ... + theta_i``. Its velocity is ``sum_{j<=k} theta_j'(r) J (p - q_{j-1})``
(q_{j-1} the position of joint j-1, J the 90 degree rotation), so
``|dp/dr| <= sum_{j<=k} |theta_j'(r)| R_{jk}`` with ``R_{jk} = l_j + ... + l_k``, which bounds
``|p - q_{j-1}|``. Around each sample r_s take the window ``|r - r_s| <= rho`` with
``rho = h / 2`` (h the sample spacing): the windows cover [0, 1]. The exact Taylor expansion of
the polynomial ``theta_j'`` at r_s bounds ``|theta_j'|`` on the window by
``M_j = sum_{m>=1} |theta_j^(m)(r_s)| rho^(m-1) / (m-1)!``, so within the window every point of
link k stays within ``delta_k = rho sum_j M_j R_{jk}`` of where it is at r_s. If c_k is a lower
bound on link k's distance to the nearest obstacle at r_s (``world.separation_bound_xy``: exact
for circles, the separating-axis gap for polygons), then ``c_k >= delta_k`` for every link proves
that no point of the arm enters an obstacle's interior during the window (obstacles are open
sets, see ``world``). Each window's *shortfall* is ``max_k (delta_k - c_k)``; it is <= 0 iff the
window is certified. The first ``refine_intervals`` failing windows of a path are split into
``refine_factor`` sub-windows, each tested the same way about its own centre with its own
radius (the speed bound's tail taken over the whole window). A motion with a window left uncertified is reported as colliding (conservative). The
guarantee holds up to floating-point rounding of the geometry.

Each test reads one posture and the path's derivatives at one time, so a window's shortfall is
a single value computed in a single fused loop; a test that compares neighbouring samples would
need several values per step, which XLA computes in separate loops, repeating the geometry.

Violation (for constraint handling): in sampled mode the penetration depth summed over links,
obstacles and samples, times the sample spacing (about the integral of penetration over r, in
cm); in certified mode the positive shortfalls of the windows summed, times the spacing (a
penetrating sample has a shortfall of at least its depth). In both modes ``violation == 0``
exactly when the motion counts as collision-free.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import path, world as world_lib
from jaxarm.arm import link_endpoints


def penetration(lengths, world, theta):
    """Penetration depth of every link into every obstacle slot.

    Args:
      lengths: link lengths, shape (n_joints,).
      world: ``WorldArrays``.
      theta: joint angles, shape (..., n_joints).

    Returns:
      Array of shape (..., n_joints, n_obstacle_slots), >= 0.
    """
    links = link_endpoints(lengths, theta)
    return jnp.stack([jnp.moveaxis(world_lib.penetration_xy(*link, world), 0, -1)
                      for link in links], axis=-2)


def _nearest(separation):
    """Min over obstacle slots (the leading axis); +inf for a world without obstacles."""
    if separation.shape[0] == 0:
        return jnp.full(separation.shape[1:], jnp.inf, separation.dtype)
    return separation.min(axis=0)


def posture_penetration(lengths, world, theta: list):
    """Penetration summed over links and obstacle slots at one posture per path.

    Args:
      theta: per-joint angles, each of shape (...,).

    Returns:
      Array of shape (...,), >= 0, zero iff no link overlaps any obstacle.
    """
    return sum(world_lib.penetration_xy(*link, world).sum(axis=0)
               for link in link_endpoints(lengths, theta))


def posture_clearance_bound(lengths, world, theta: list) -> list:
    """Lower bounds on every link's distance to the nearest obstacle at one posture per path.

    Args:
      theta: per-joint angles, each of shape (...,).

    Returns:
      A list of n_joints arrays of shape (...,); negative values are minus a penetration depth.
    """
    return [_nearest(world_lib.separation_bound_xy(*link, world))
            for link in link_endpoints(lengths, theta)]


def sampled_fold(lengths, world, x, n_samples: int) -> path.SampleFold:
    """The paper's check as a fold: penetration summed over the samples, times their spacing;
    shape (...,), >= 0, zero iff no sample collides.

    Args:
      lengths, world: the problem's arrays.
      x: free parameters, shape (..., n_free) (for the batch shape and dtype).
    """
    return path.SampleFold(
        init=jnp.zeros(x.shape[:-1], x.dtype),
        step=lambda total, sample: total + posture_penetration(lengths, world,
                                                               sample.derivatives[0]),
        finish=lambda total: total / (n_samples - 1),
        max_order=0,
    )


def reach_matrix(lengths):
    """``R[j, k] = l_j + ... + l_k`` for j <= k, else 0: how far joint j-1 is from link k's far end.

    Args:
      lengths: link lengths, shape (n_joints,) (may be traced).

    Returns:
      Array of shape (n_joints, n_joints).
    """
    cumulative = jnp.concatenate([jnp.zeros(1, lengths.dtype), jnp.cumsum(lengths)])
    reach = cumulative[None, 1:] - cumulative[:-1, None]
    upper = np.triu(np.ones((lengths.shape[-1],) * 2, dtype=bool))
    return jnp.where(upper, reach, 0.0)


def _tail_weights(degree: int, centres: np.ndarray, radius: float, spread: float = 0.0):
    """Weights ``T_q`` bounding the Taylor tail of every basis function's derivative.

    For a path ``theta = theta_i + Delta q_0 + sum_p a_p q_p`` (``path.basis_values``) and any r
    within ``radius`` of a centre c, ``|theta'(r)| <= |theta'(c)| + |Delta| T_0 + sum_p |a_p|
    T_p`` with ``T_q = sum_{m>=2} sup |q^(m)| radius^(m-1) / (m-1)!`` (exact Taylor expansion of
    a polynomial, then the triangle inequality). The sup is over centres within ``spread`` of
    the given ones, bounded by a second exact expansion; computed in float64.

    Args:
      centres: times, shape (n,).

    Returns:
      Array of shape (n, degree - 4).
    """
    derivatives = [np.abs(path.basis_values(degree, centres, order))
                   for order in range(degree + 1)]
    total = np.zeros_like(derivatives[0])
    for order in range(2, degree + 1):
        sup = sum(derivatives[order + n] * spread**n / math.factorial(n)
                  for n in range(degree + 1 - order))
        total += sup * radius ** (order - 1) / math.factorial(order - 1)
    return total


def _speed_bound(start, goal, x, velocity: list, tail) -> list:
    """Bounds on |theta_j'| over a window, from the velocity at its centre and tail weights.

    Args:
      velocity: per-joint ``theta_j'`` at the window's centre, each of shape (...,).
      tail: ``_tail_weights`` of the window, shape (degree - 4,) or (..., degree - 4).

    Returns:
      A list of n_joints arrays of shape (...,).
    """
    delta = jnp.abs(jnp.asarray(goal, x.dtype) - jnp.asarray(start, x.dtype))
    tails = path.joint_angle_list(jnp.zeros_like(delta), delta, jnp.abs(x), tail, order=1,
                                  per_path=tail.ndim > 1)
    return [jnp.abs(v) + t for v, t in zip(velocity, tails)]


def window_shortfall(lengths, world, theta: list, speed: list, radius: float):
    """How far the window ``|r - r_c| <= radius`` around a posture is from certified (cm).

    Args:
      lengths, world: the problem's arrays.
      theta: per-joint angles at the centre r_c, each of shape (...,).
      speed: per-joint bounds on |theta_j'| over the window (``_speed_bound``), each (...,).
      radius: the window's half-width in r.

    Returns:
      Array of shape (...,): ``max_k (delta_k - c_k)``, <= 0 iff the window is certified free.
    """
    reach = reach_matrix(jnp.asarray(lengths, dtype=theta[0].dtype))
    clearance_bounds = posture_clearance_bound(lengths, world, theta)
    return functools.reduce(jnp.maximum, [
        radius * sum(speed[j] * reach[j, k] for j in range(k + 1)) - bound
        for k, bound in enumerate(clearance_bounds)
    ])


class _FailingWindows(NamedTuple):
    """Running record of the windows that failed, carried along the samples."""

    pending: jax.Array  # shape=(...,), the previous sample's shortfall, not yet recorded
    count: jax.Array  # shape=(...,), int32: failing windows recorded so far
    first: jax.Array  # shape=(n_refined, ...), int32: sample indices of the first failures
    excess: jax.Array  # shape=(...,), summed shortfall of failures beyond the first n_refined


def _record(record: _FailingWindows, index) -> _FailingWindows:
    """Record ``record.pending`` as the shortfall of the window around sample ``index``."""
    failing = ~(record.pending <= 0)  # NaN (from non-finite angles) fails too
    slot = jnp.arange(record.first.shape[0]).reshape((-1,) + (1,) * record.count.ndim)
    return record._replace(
        count=record.count + failing,
        first=jnp.where(failing & (slot == record.count), index, record.first),
        excess=record.excess + jnp.where(failing & (record.count >= record.first.shape[0]),
                                         record.pending, 0.0),
    )


def certified_fold(lengths, world, start, goal, x, degree: int, n_samples: int,
                   refine_intervals: int, refine_factor: int) -> path.SampleFold:
    """The certified continuous check as a fold (see the module docstring): the violation,
    shape (...,), >= 0, zero iff every window is certified free.

    Along the samples it tests every sample's window and records the first
    ``refine_intervals`` failing windows of each path; ``finish`` splits those into
    ``refine_factor`` sub-windows. (Which failing windows are split does not change the
    verdict: a path with more failing windows than that stays uncertified anyway.)

    Args:
      lengths, world, start, goal: the problem's arrays.
      x: free parameters, shape (..., n_free).
      degree, n_samples, refine_intervals, refine_factor: static sizes.
    """
    step = 1.0 / (n_samples - 1)
    n_refined = min(refine_intervals, n_samples) if refine_factor > 1 else 0
    tails = jnp.asarray(_tail_weights(degree, np.linspace(0.0, 1.0, n_samples), step / 2),
                        x.dtype)

    def add_sample(record, sample):
        theta, velocity = sample.derivatives
        speed = _speed_bound(start, goal, x, velocity, tails[sample.index])
        # The shortfall waits one step in the carry before it is recorded: the fusion that
        # computes it then has one output, and XLA does not repeat the geometry per output.
        record = _record(record, sample.index - 1)
        return record._replace(pending=window_shortfall(lengths, world, theta, speed, step / 2))

    def finish(record):
        record = _record(record, n_samples - 1)
        if n_refined == 0:
            return record.excess * step
        return record.excess * step + _subdivided_shortfall(
            lengths, world, start, goal, x, degree, record.first, record.count, n_samples,
            refine_factor)

    batch = x.shape[:-1]
    empty = _FailingWindows(pending=jnp.full(batch, -jnp.inf, x.dtype),
                            count=jnp.zeros(batch, jnp.int32),
                            first=jnp.zeros((n_refined,) + batch, jnp.int32),
                            excess=jnp.zeros(batch, x.dtype))
    return path.SampleFold(init=empty, step=add_sample, finish=finish, max_order=1)


def _subdivided_shortfall(lengths, world, start, goal, x, degree, windows, n_windows,
                          n_samples, refine_factor):
    """Positive shortfall of sample windows split into ``refine_factor`` sub-windows, summed
    over the sub-windows and times their width.

    Args:
      windows: sample indices, shape (n_refined, ...), int; only the first ``n_windows``
        of each path are used.
      n_windows: shape (...,), int.

    Returns:
      Array of shape (...,), zero iff every sub-window is certified.
    """
    step = 1.0 / (n_samples - 1)
    radius = step / (2 * refine_factor)
    r = np.linspace(0.0, 1.0, n_samples)
    # Sub-window centres tile each sample's window [r_s - step / 2, r_s + step / 2].
    centres = r[:, None] + step * ((np.arange(refine_factor) + 0.5) / refine_factor - 0.5)
    # Flat tables, one per basis function, read with one index per path: a gather of single
    # values fuses, where gathering rows would materialise strided (..., degree - 4) arrays.
    basis = [[jnp.asarray(column, x.dtype) for column in
              path.basis_values(degree, centres.ravel(), order).T] for order in (0, 1)]
    tails = [jnp.asarray(column, x.dtype)
             for column in _tail_weights(degree, r, radius, spread=step / 2).T]
    n_refined = windows.shape[0]
    pieces = (np.repeat(np.arange(n_refined), refine_factor),
              np.tile(np.arange(refine_factor), n_refined))

    def add_piece(total, piece):
        slot, offset = piece
        window = windows[slot]  # (...,)
        index = window * refine_factor + offset
        theta, velocity = (
            path.joint_angle_list(start, goal, x, jnp.stack([c[index] for c in columns], -1),
                                  order, per_path=True)
            for order, columns in enumerate(basis))
        speed = _speed_bound(start, goal, x, velocity, jnp.stack([c[window] for c in tails], -1))
        shortfall = window_shortfall(lengths, world, theta, speed, radius)
        return total + jnp.where(slot < n_windows, jnp.maximum(shortfall, 0.0), 0.0), None

    total, _ = jax.lax.scan(add_piece, jnp.zeros(x.shape[:-1], x.dtype), pieces)
    return total * (step / refine_factor)
