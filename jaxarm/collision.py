"""Collision checks of a whole motion: the paper's sampled check and a certified continuous one.

``sampled`` (the paper's Fig. 8): the links are checked against every obstacle at the ``n``
equally spaced samples of r. A thin obstacle can slip between two samples.

``certified``: a guarantee that every link is collision-free for every r in [0, 1].

Proof sketch. A point p of link k is ``p = sum_{i<k} l_i u(phi_i) + t l_k u(phi_k)`` with
``phi_i = theta_1 + ... + theta_i``. Its velocity is ``sum_{j<=k} theta_j'(r) J (p - q_{j-1})``
(q_{j-1} the position of joint j-1, J the 90 degree rotation), so
``|dp/dr| <= sum_{j<=k} |theta_j'(r)| R_{jk}`` with ``R_{jk} = l_j + ... + l_k``, which bounds
``|p - q_{j-1}|``. On an interval [r_s, r_s + h], ``M_j`` bounds ``|theta_j'|``: the exact
Taylor expansion of the polynomial ``theta_j'`` at either end gives
``|theta_j'(r_s + t)| <= sum_{m>=1} |theta_j^(m)(r_s)| h^(m-1) / (m-1)!`` (we take the smaller of
the expansions from both ends). So each point of link k moves at most
``delta_k = h sum_j M_j R_{jk}`` over the interval, split as D1 + D2 <= delta_k before and
after any instant r. If c_s and c_{s+1} are the link's clearances (distance to the nearest
obstacle) at the two ends, the point's clearance at r is at least
``max(c_s - D1, c_{s+1} - D2) >= (c_s + c_{s+1} - delta_k) / 2``. Hence
``c_s >= 0, c_{s+1} >= 0 and c_s + c_{s+1} >= delta_k`` for every link proves that no point
enters an obstacle's interior during the interval (obstacles are open sets, see ``world``). Intervals where this fails are subdivided: the ``refine_intervals`` worst intervals are
split into ``refine_factor`` pieces (postures there from the same exact Taylor expansion, the
speed bound of the whole interval reused) and the same test is applied to every piece. A motion with
a failing interval left over is reported as colliding (conservative). The guarantee holds up
to floating-point rounding of the geometry.

Violation (for constraint handling) is the penetration depth summed over links, obstacles and
samples, times the sample spacing (about the integral of penetration over r, in cm); in
certified mode the clearance deficit of intervals that could not be certified is added, so in
both modes ``violation == 0`` exactly when the motion counts as collision-free.
"""

from __future__ import annotations

import math

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


def total_penetration(lengths, world, theta):
    """Penetration summed over links, obstacles and the last batch axis (the samples).

    Args:
      theta: joint angles, shape (..., n_samples, n_joints).

    Returns:
      Array of shape (...,).
    """
    return sum(world_lib.penetration_xy(*link, world).sum(axis=(0, -1))
               for link in link_endpoints(lengths, theta))


def _nearest(separation):
    """Min over obstacle slots (the leading axis); +inf for a world without obstacles."""
    if separation.shape[0] == 0:
        return jnp.full(separation.shape[1:], jnp.inf, separation.dtype)
    return separation.min(axis=0)


def clearance(lengths, world, theta):
    """Signed distance of every link to the nearest obstacle (negative: penetration depth).

    Args:
      theta: joint angles, shape (..., n_joints).

    Returns:
      Array of shape (..., n_joints).
    """
    links = link_endpoints(lengths, theta)
    return jnp.stack([_nearest(world_lib.separation_xy(*link, world)) for link in links], axis=-1)


def clearance_and_penetration(lengths, world, theta):
    """``clearance`` and ``total_penetration`` from one pass over the geometry.

    Args:
      theta: joint angles, shape (..., n_samples, n_joints).

    Returns:
      Clearance of shape (..., n_samples, n_joints) and total penetration of shape (...,).
    """
    separations = [world_lib.separation_xy(*link, world)
                   for link in link_endpoints(lengths, theta)]
    depth = sum(jnp.maximum(-s, 0.0).sum(axis=(0, -1)) for s in separations)
    return jnp.stack([_nearest(s) for s in separations], axis=-1), depth


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


def _taylor_speed(derivatives, step: float):
    """Bound on |theta_j'| over [r_s, r_s + step] from the exact Taylor expansion at r_s.

    Args:
      derivatives: ``[theta, theta', ..., theta^(d)]`` at the samples, each (..., n_s, n_joints).
      step: signed interval length (negative expands backwards from r_s).

    Returns:
      Array of shape (..., n_s, n_joints).
    """
    return sum(
        jnp.abs(derivatives[order]) * (abs(step) ** (order - 1) / math.factorial(order - 1))
        for order in range(1, len(derivatives))
    )


def _sweep(lengths, speed, step: float):
    """How far any point of each link can move over an interval, ``step * sum_j M_j R_jk``.

    Args:
      speed: bounds ``M_j`` on |theta_j'| over each interval, shape (..., n_intervals, n_joints).

    Returns:
      Array of shape (..., n_intervals, n_joints).
    """
    reach = reach_matrix(jnp.asarray(lengths, dtype=speed.dtype))
    # Unrolled over the few joints: elementwise work fuses, a tiny matmul does not.
    return sum(speed[..., j, None] * reach[j] for j in range(reach.shape[0])) * step


def _deficit(sweep, c_left, c_right):
    """How far each interval is from certified: <= 0 iff, for every link, both ends are free
    (clearance >= 0) and ``sweep <= c_left + c_right``; otherwise positive (cm).

    Args:
      sweep, c_left, c_right: shape (..., n_intervals, n_joints).

    Returns:
      Array of shape (..., n_intervals).
    """
    per_link = jnp.maximum(sweep - c_left - c_right, jnp.maximum(-c_left, -c_right))
    return per_link.max(axis=-1)


def certified_deficit(
    lengths, world, start, goal, x, link_clearance, degree: int,
    refine_intervals: int, refine_factor: int,
):
    """Per-interval certification deficit after subdividing the worst intervals.

    Args:
      lengths, world, start, goal: the problem's arrays.
      x: free parameters, shape (..., n_free).
      link_clearance: ``clearance`` of every link at the n equally spaced samples of r,
        shape (..., n_samples, n_joints).
      degree: path degree (static).
      refine_intervals: how many of the worst intervals are subdivided (static).
      refine_factor: pieces each of those intervals is split into (static).

    Returns:
      Array of shape (..., n_samples - 1): <= 0 where the interval is certified free, the
      clearance deficit (cm, > 0) where it is not.
    """
    n_samples = link_clearance.shape[-2]
    r = np.linspace(0.0, 1.0, n_samples)
    step = 1.0 / (n_samples - 1)
    derivatives = [
        path.joint_angles(start, goal, x, path.basis_values(degree, r, order), order)
        for order in range(degree + 1)
    ]
    speed = jnp.minimum(
        _taylor_speed(derivatives, step)[..., :-1, :],
        _taylor_speed(derivatives, -step)[..., 1:, :],
    )
    sweep = _sweep(lengths, speed, step)
    deficit = _deficit(sweep, link_clearance[..., :-1, :], link_clearance[..., 1:, :])
    n_refined = min(refine_intervals, n_samples - 1)
    if n_refined == 0 or refine_factor < 2:
        return deficit

    _, worst = jax.lax.top_k(deficit, n_refined)  # (..., F)
    gather = lambda a, offset=0: jnp.take_along_axis(a, worst[..., None] + offset, axis=-2)  # noqa: E731
    # The polynomial's exact Taylor expansion about each interval's left end gives the
    # postures at the inner sub-points from derivatives already at hand.
    offsets = step * np.arange(1, refine_factor) / refine_factor
    theta_inner = sum(
        gather(derivative)[..., None, :]
        * jnp.asarray(offsets**order / math.factorial(order), dtype=x.dtype)[:, None]
        for order, derivative in enumerate(derivatives)
    )  # (..., F, K - 1, n_joints)
    c_fine = jnp.concatenate(
        [
            gather(link_clearance)[..., None, :],
            clearance(lengths, world, theta_inner),
            gather(link_clearance, 1)[..., None, :],
        ],
        axis=-2,
    )  # (..., F, K + 1, n_joints)
    # Each piece is 1/K of the interval, so the interval's speed bound gives 1/K of its sweep.
    sweep_fine = gather(sweep)[..., None, :] / refine_factor
    fine_deficit = _deficit(sweep_fine, c_fine[..., :-1, :], c_fine[..., 1:, :]).max(axis=-1)
    return jnp.put_along_axis(deficit, worst, fine_deficit, axis=-1, inplace=False)
