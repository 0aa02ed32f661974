"""Collision checks of a whole motion, and the geometry the certified check shares.

``sampled`` (the paper's Fig. 8): the links are checked against every obstacle at the ``n``
equally spaced samples of r, a fold along the samples (``path.run_fold``). A thin obstacle can
slip between two samples. With a margin m > 0 a link closer than m to an obstacle counts too
(exact distances then; without a margin the separating-axis gap suffices, see ``world``).

Violation (for constraint handling): ``max(m - separation, 0)`` summed over links and
obstacles at a sample, the largest such sum over the samples (cm: the deepest penetration
found); zero exactly when no sample collides. The deepest penetration rather than its sum over
the samples: the sum rewards paths that swing fast through an obstacle (fewer samples inside),
and under feasibility rules it drew more swarms into such traps (``benchmarks/RESULTS.md``,
*Decisions and negative results*, "Constraint rules compare depth x distance"). The constraint
rules compare it times the path's travelling distance (``constraints.path_measures``).

The certified continuous check lives in ``jaxarm.checks.certified``; its per-window test
(``window_shortfall``, with ``reach_matrix``, ``tail_weights`` and ``speed_bound``) is here.
"""

from __future__ import annotations

import functools
import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import rank_promotion_allowed
from jaxarm.model import path
from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints, sincos

# Written out, XLA fuses every link's exact polygon distances into one kernel, which runs far
# slower past about this many link-edge pairs; one link at a time (a scan) is slower on small
# worlds, so the scan starts above it (benchmarks/RESULTS.md, Decisions and negative results,
# "The sampled check with a margin on polygon-field").
UNROLLED_LINK_EDGES = 64


def link_edge_pairs(n_links: int, world) -> int:
    """Links x polygon slots x vertex slots: the exact distances one posture's check takes."""
    return n_links * world.vertices.shape[0] * world.vertices.shape[1]


def posture_penetration(lengths, world, theta: list, margin=0.0, exact: bool = False):
    """How far every link is inside the margin around every obstacle, summed, at one posture
    per path.

    Args:
      theta: per-joint angles, each of shape (...,).
      margin: cm, a scalar.
      exact: exact distances (needed for a positive margin), or the separating-axis bound
        for polygons (exact where <= 0: enough for margin 0); see ``world.polygon_slots``.

    Returns:
      Array of shape (...,), >= 0, zero iff every link keeps the margin from every obstacle.

    With exact distances and more than ``UNROLLED_LINK_EDGES`` link-edge pairs
    (``link_edge_pairs``), the links are taken one at a time, in a ``lax.scan``.
    """
    links = link_endpoints(lengths, theta)
    total = jnp.zeros_like(theta[0])
    if exact and link_edge_pairs(len(links), world) > UNROLLED_LINK_EDGES:
        stacked = tuple(jnp.stack(coordinate) for coordinate in zip(*links))
        total, _ = jax.lax.scan(
            lambda total, link: (_add_link_penetration(total, link, world, margin, exact), None),
            total, stacked)
        return total
    for link in links:
        total = _add_link_penetration(total, link, world, margin, exact)
    return total


def _add_link_penetration(total, link, world, margin, exact: bool):
    """``total`` plus how far one link (its end points' coordinates) is inside the margin
    around every obstacle slot, added slot by slot."""
    for separation in (world_lib.circle_slots(*link, world)
                       + world_lib.polygon_slots(*link, world, exact)):
        total = total + jnp.maximum(margin - separation, 0.0)
    return total


def posture_clearance_bound(lengths, world, theta: list, exact: bool = False) -> list:
    """Lower bounds on every link's distance to the nearest obstacle at one posture per path.

    Args:
      theta: per-joint angles, each of shape (...,).
      exact: exact distances, or the cheaper bound (``world.separation_parts``).

    Returns:
      A list of n_joints arrays of shape (...,); negative values are minus a penetration
      depth; +inf for a world without obstacles.
    """
    bounds = []
    for link in link_endpoints(lengths, theta):
        parts = world_lib.separation_parts(*link, world, exact)
        nearest = functools.reduce(jnp.minimum, parts.circles, jnp.full_like(theta[0], jnp.inf))
        if parts.polygons is not None:
            nearest = jnp.minimum(nearest, parts.polygons.min(axis=0))
        bounds.append(nearest)
    return bounds


def sampled_fold(lengths, world, x, n_samples: int, margin=0.0,
                 exact: bool = False) -> path.SampleFold:
    """The paper's check as a fold: the deepest penetration (into the margin) over the samples,
    in cm; shape (...,), >= 0, zero iff no sample collides.

    Args:
      lengths, world: the problem's arrays.
      x: free parameters, shape (..., n_free) (for the batch shape and dtype).
      margin: cm, a scalar (may be traced).
      exact: use exact distances (required when the margin may be positive).
    """
    return path.SampleFold(
        init=jnp.zeros(x.shape[:-1], x.dtype),
        step=lambda deepest, sample: jnp.maximum(deepest, posture_penetration(
            lengths, world, sample.derivatives[0], margin, exact)),
        finish=lambda deepest: deepest,
        max_order=0,
    )


def reach_matrix(lengths):
    """``R[j, k] = l_j + ... + l_k`` for j <= k, else 0: how far joint j-1 can be from link k's
    far end.

    Args:
      lengths: link lengths, shape (n_joints,) (may be traced).

    Returns:
      Array of shape (n_joints, n_joints).
    """
    cumulative = jnp.concatenate([jnp.zeros(1, lengths.dtype), jnp.cumsum(lengths)])
    reach = cumulative[None, 1:] - cumulative[:-1, None]
    upper = np.triu(np.ones((lengths.shape[-1],) * 2, dtype=bool))
    return jnp.where(upper, reach, 0.0)


def tail_weights(degree: int, centres: np.ndarray, radius: float):
    """Weights ``T_q`` bounding the Taylor tail of every basis function's derivative.

    For a path ``theta = theta_i + Delta q_0 + sum_p a_p q_p`` (``path.basis_values``) and any r
    within ``radius`` of a centre c, ``|theta'(r)| <= |theta'(c)| + |Delta| T_0 + sum_p |a_p|
    T_p`` with ``T_q = sum_{m>=2} |q^(m)(c)| radius^(m-1) / (m-1)!`` (exact Taylor expansion of
    a polynomial, then the triangle inequality); computed in float64.

    Args:
      centres: times, shape (n,).

    Returns:
      Array of shape (n, degree - 4).
    """
    total = np.zeros((len(centres), degree - 4))
    for order in range(2, degree + 1):
        total += (np.abs(path.basis_values(degree, centres, order))
                  * radius ** (order - 1) / math.factorial(order - 1))
    return total


def speed_bound(start, goal, x, velocity: list, tail) -> list:
    """Bounds on |theta_j'| over a window, from the velocity at its centre and tail weights.

    Args:
      velocity: per-joint ``theta_j'`` at the window's centre, each of shape (...,).
      tail: ``tail_weights`` of the window, shape (degree - 4,) or (..., degree - 4).

    Returns:
      A list of n_joints arrays of shape (...,).
    """
    delta = jnp.abs(jnp.asarray(goal, x.dtype) - jnp.asarray(start, x.dtype))
    tails = path.joint_angle_list(jnp.zeros_like(delta), delta, jnp.abs(x), tail, order=1,
                                  per_path=tail.ndim > 1)
    return [jnp.abs(v) + t for v, t in zip(velocity, tails)]


def window_shortfall(lengths, world, theta: list, speed: list, radius, margin=0.0,
                     exact: bool = False):
    """How far the window ``|r - r_c| <= radius`` around a posture is from certified (cm).

    Args:
      lengths, world: the problem's arrays.
      theta: per-joint angles at the centre r_c, each of shape (...,).
      speed: per-joint bounds on |theta_j'| over the window (``speed_bound``), each (...,).
      radius: the window's half-width in r, a scalar or shape (...,).
      margin: the clearance to keep (cm).
      exact: how the clearance at the centre is bounded (``posture_clearance_bound``).

    Returns:
      ``(shortfall, nearest)``, each of shape (...,): ``max_k (delta_k - (c_k - margin))``,
      <= 0 iff the window is certified, and ``min_k c_k``, the nearest link's clearance
      bound at the centre (< 0: a penetration, exact).
    """
    shortfalls, nearest = link_shortfalls(lengths, world, theta, speed, radius, margin, exact)
    return functools.reduce(jnp.maximum, shortfalls), nearest


def link_shortfalls(lengths, world, theta: list, speed: list, radius, margin=0.0,
                    exact: bool = False):
    """``window_shortfall`` link by link: ``([delta_k - (c_k - margin) for each link k],
    min_k c_k)``."""
    reach = reach_matrix(jnp.asarray(lengths, dtype=theta[0].dtype))
    bounds = posture_clearance_bound(lengths, world, theta, exact)
    shortfalls = [radius * sum(speed[j] * reach[j, k] for j in range(k + 1)) - (bound - margin)
                  for k, bound in enumerate(bounds)]
    return shortfalls, functools.reduce(jnp.minimum, bounds)


def sweep_shortfalls(lengths, world, about_centre: list, radius, margin=0.0) -> list:
    """Per link, how far the piece ``|r - c| <= radius`` is from certified by a second-order
    bound (cm): ``e_k - (h_k - margin)``, <= 0 proves link k clear of every obstacle there.

    Every point X of link k moves as ``X(c) + s X'(c) + E`` (``s = r - c``). The linear part
    of the whole link lies in the convex hull of its end points' four positions ``q(c) +/-
    radius q'(c)`` (a segment whose end points move linearly sweeps a bilinear patch, inside
    that hull), and ``|E| <= e_k = radius^2 / 2 * max |X''|`` with ``|X''| <= sum_{i<=k} l_i
    (|phi_i''| + phi_i'^2)`` (``phi_i = theta_1 + ... + theta_i``; the bounds on ``|phi_i'|``
    and ``|phi_i''|`` over the piece come from its exact Taylor expansion). So link k's
    signed distance to an obstacle (minus a penetration depth when they overlap) is at least
    ``h_k - e_k``, with ``h_k`` the hull's separating-axis gap (``hull_separation``: where the
    hull overlaps the obstacle it is at most minus the hull's penetration depth, which is at
    least the linear part's). A path that grazes an obstacle, its distance ``c + a s^2`` near
    the closest approach, is proved with pieces of radius about ``sqrt(c / a)``: a few pieces
    where the first-order bound (``link_shortfalls``) needs ``1 / sqrt(c)`` of them.

    Args:
      lengths, world: the problem's arrays.
      about_centre: ``about_centre[m][j] = theta_j^(m)(c) / m!`` for m = 0 .. degree, each
        of shape (...,).
      radius: the piece's half-width in r, a scalar or shape (...,).
      margin: the clearance to keep (cm).

    Returns:
      A list of n_joints arrays of shape (...,).
    """
    degree = len(about_centre) - 1
    lengths = jnp.asarray(lengths, dtype=about_centre[0][0].dtype)
    phi = [list(itertools.accumulate(order)) for order in about_centre]  # phi[m][i]
    x = y = vx = vy = jnp.zeros_like(about_centre[0][0])
    curvature = 0.0
    shortfalls = []
    for k in range(len(phi[0])):
        rate = sum(m * jnp.abs(phi[m][k]) * radius ** (m - 1) for m in range(1, degree + 1))
        turn = sum(m * (m - 1) * jnp.abs(phi[m][k]) * radius ** (m - 2)
                   for m in range(2, degree + 1))
        curvature = curvature + lengths[k] * (turn + rate * rate)
        sine, cosine = sincos(phi[0][k])
        next_x, next_y = x + lengths[k] * cosine, y + lengths[k] * sine
        next_vx = vx - lengths[k] * phi[1][k] * sine
        next_vy = vy + lengths[k] * phi[1][k] * cosine
        hull = hull_separation(world, [
            (x - radius * vx, y - radius * vy), (x + radius * vx, y + radius * vy),
            (next_x + radius * next_vx, next_y + radius * next_vy),
            (next_x - radius * next_vx, next_y - radius * next_vy)])
        shortfalls.append(0.5 * radius * radius * curvature - (hull - margin))
        x, y, vx, vy = next_x, next_y, next_vx, next_vy
    return shortfalls


_CORNER_PAIRS = tuple(itertools.combinations(range(4), 2))  # every hull edge is one of them


@rank_promotion_allowed
def hull_separation(world, corners: list):
    """A lower bound on the signed distance from the convex hull of four points to the nearest
    obstacle (cm; negative where they may overlap: at most minus the penetration depth);
    +inf without obstacles.

    The largest gap between the projections of the hull and of an obstacle on a few axes
    (separating axes): the normals of the six segments between the corners (every hull edge is
    one of them) and, for polygons, their edge normals. A gap on any axis is at most the
    distance (where the sets overlap, every axis's overlap is at least the smallest
    translation that parts them), and on the axis normal to the hull edge facing an obstacle
    it is the distance: the case of a link sweeping past an obstacle. Near a corner of both it
    can be less. It is cheaper than the hull's exact distance, which takes six segments'
    distances and a test for an obstacle inside the hull.

    Args:
      corners: four ``(x, y)`` pairs, each coordinate of shape (...,).

    Returns:
      Array of shape (...,).
    """
    dtype = corners[0][0].dtype
    axes = []  # (nx, ny, the hull's lowest and highest projection on the axis)
    for i, j in _CORNER_PAIRS:
        nx, ny = world_lib.unit_normal(*corners[i], *corners[j])
        axes.append((nx, ny, *_projection_range(nx, ny, corners)))
    nearest = jnp.full(corners[0][0].shape, jnp.inf, dtype)
    circles = jnp.asarray(world.circles, dtype)
    for i in range(circles.shape[0]):
        px, py = circles[i, 0], circles[i, 1]
        gap = functools.reduce(jnp.maximum, [
            jnp.maximum(nx * px + ny * py - high, low - (nx * px + ny * py))
            for nx, ny, low, high in axes]) - circles[i, 2]
        nearest = jnp.minimum(nearest, jnp.where(world.circle_valid[i], gap, jnp.inf))
    if world.vertices.shape[0]:
        slots = functools.partial(world_lib.leading_slots, ndim=corners[0][0].ndim)
        vertices = jnp.asarray(world.vertices, dtype)
        normals = jnp.asarray(world.normals, dtype)
        low_extent, high_extent = (jnp.asarray(a, dtype)
                                   for a in (world.extent_low, world.extent_high))
        valid = [slots(world.edge_valid[:, v]) for v in range(vertices.shape[1])]
        gap = jnp.full((vertices.shape[0],) + corners[0][0].shape, -jnp.inf, dtype)
        for v in range(vertices.shape[1]):  # the polygons' edge normals
            low, high = _projection_range(slots(normals[:, v, 0]), slots(normals[:, v, 1]),
                                          corners)
            edge_gap = jnp.maximum(low - slots(high_extent[:, v]),
                                   slots(low_extent[:, v]) - high)
            gap = jnp.maximum(gap, jnp.where(valid[v], edge_gap, -jnp.inf))
        for nx, ny, low, high in axes:  # the hull's
            along = [nx * slots(vertices[:, v, 0]) + ny * slots(vertices[:, v, 1])
                     for v in range(vertices.shape[1])]
            lowest = functools.reduce(jnp.minimum, [jnp.where(ok, a, jnp.inf)
                                                    for a, ok in zip(along, valid)])
            highest = functools.reduce(jnp.maximum, [jnp.where(ok, a, -jnp.inf)
                                                     for a, ok in zip(along, valid)])
            gap = jnp.maximum(gap, jnp.maximum(lowest - high, low - highest))
        nearest = jnp.minimum(nearest, jnp.where(slots(world.polygon_valid), gap,
                                                 jnp.inf).min(axis=0))
    return nearest


def _projection_range(nx, ny, points: list) -> tuple:
    """The lowest and highest projection of ``points`` ((x, y) pairs) on the axis (nx, ny)."""
    along = [nx * x + ny * y for x, y in points]
    return functools.reduce(jnp.minimum, along), functools.reduce(jnp.maximum, along)
