"""Collision checks of a whole motion, and the geometry the certified check shares.

``sampled`` (the paper's Fig. 8): the links are checked against every obstacle at the ``n``
equally spaced samples of r, a fold along the samples (``path.run_fold``). A thin obstacle can
slip between two samples. With a margin m > 0 a link closer than m to an obstacle counts too
(exact distances then; without a margin the separating-axis gap suffices, see ``world``).

Violation (for constraint handling): ``max(m - separation, 0)`` summed over links and
obstacles at a sample, the largest such sum over the samples (cm: the deepest penetration
found); zero exactly when no sample collides. The deepest penetration rather than its sum over
the samples: the sum rewards paths that swing fast through an obstacle (fewer samples inside),
and under feasibility rules it drew more swarms into such traps (paper-case-1, preset A, 500
seeds of ``jaxarm reproduce-paper``, each compared alone: 79.6 % escape with the deepest
penetration, 60.4 % with the sum; ``benchmarks/RESULTS.md``). The constraint rules compare it
times the path's travelling distance (``constraints.path_measures``).

The certified continuous check lives in ``jaxarm.checks.certified``; its per-window test
(``window_shortfall``, with ``reach_matrix``, ``tail_weights`` and ``speed_bound``) is here.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.model import path
from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints

# Written out, XLA fuses every link's exact polygon distances into one kernel. With 3 links it
# ran about 10x slower than the links apart for 4 polygon slots of 6, 7 or 8 vertex slots and
# for 8 of 4 (72-96 link-edge pairs), not for 4 of 5, 6 of 4 or 3 of 8 (60-72). One link at a
# time (a scan) was slower on small worlds: 13-36 % in 100-restart searches on narrow-gap,
# mixed-clutter and death-trap (benchmarks/RESULTS.md, "The sampled check with a margin on
# polygon-field").
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
    reach = reach_matrix(jnp.asarray(lengths, dtype=theta[0].dtype))
    bounds = posture_clearance_bound(lengths, world, theta, exact)
    shortfall = functools.reduce(jnp.maximum, [
        radius * sum(speed[j] * reach[j, k] for j in range(k + 1)) - (bound - margin)
        for k, bound in enumerate(bounds)
    ])
    return shortfall, functools.reduce(jnp.minimum, bounds)
