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

The certified continuous check lives in ``jaxarm.checks.certified``; the bounds it tests
pieces of a motion with are here: ``drift_shortfalls`` (how far a link's points can drift over
a piece), ``link_swings`` (first order) and ``sweep_shortfalls`` (second and third order, with
``hull_separation``).
"""

from __future__ import annotations

import functools
import itertools
import math
from typing import NamedTuple

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
      exact: exact distances (``world.separation_parts``, polygon slots as an array axis:
        written out slot by slot, the certified bisection took far longer to compile), or the
        cheaper bound, polygons slot by slot (``world.polygon_slots``: with the slots as an
        axis, the certified check's samples and windows ran far slower on polygon scenes;
        ``benchmarks/RESULTS.md``, *Decisions and negative results*, "Polygons slot by slot in
        the certified check's samples and windows")

    Returns:
      A list of n_joints arrays of shape (...,); negative values are minus a penetration
      depth; +inf for a world without obstacles.
    """
    return link_clearance_bounds(world, link_endpoints(lengths, theta), exact)


def link_clearance_bounds(world, links: list, exact: bool = False) -> list:
    """``posture_clearance_bound`` of links given by their end points (``link_endpoints``'s
    tuples, each coordinate of shape (...,))."""
    if exact:
        return [smallest_separation(world_lib.separation_parts(*link, world), link[0])
                for link in links]
    return [_smallest(world_lib.circle_slots(*link, world)
                      + world_lib.polygon_slots(*link, world, exact=False),
                      jnp.full_like(link[0], jnp.inf)) for link in links]


def smallest_separation(parts: world_lib.SeparationParts, like):
    """The smallest of links' separations from every obstacle, of ``like``'s shape and type
    (+inf without obstacles)."""
    nearest = (jnp.full_like(like, jnp.inf) if parts.polygons is None
               else parts.polygons.min(axis=0))
    return _smallest(parts.circles, nearest)


def _smallest(values: list, initial):
    """The elementwise minimum of ``initial`` and a list of arrays."""
    return functools.reduce(jnp.minimum, values, initial)


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


def link_swings(lengths, speed: list, radius) -> list:
    """How far any point of each link can move over the piece ``|r - c| <= radius``, when
    ``speed_j`` bounds ``|theta_j'|`` there (cm): ``[radius sum_{j<=k} speed_j R_{jk} for each
    link k]`` (``reach_matrix``). A link whose clearance at c (``link_clearance_bounds``) less
    the margin is at least its swing is clear over the piece: the first-order bound.

    Args:
      lengths: link lengths, shape (n_joints,).
      speed: per joint, each of shape (...,).
      radius: scalar or shape (...,).
    """
    reach = reach_matrix(jnp.asarray(lengths, dtype=speed[0].dtype))
    return [radius * sum(speed[j] * reach[j, k] for j in range(k + 1))
            for k in range(len(speed))]


def taylor_derivative_bound(coefficients: list, radius, order: int = 1):
    """A bound on ``|f^(order)(r)|`` for ``|r - c| <= radius``, from a polynomial's Taylor
    coefficients about c (``coefficients[m] = f^(m)(c) / m!``, each of shape (...,)):
    ``sum_m m! / (m - order)! |coefficients[m]| radius^(m - order)``, the triangle inequality
    on its exact expansion."""
    return sum(math.perm(m, order) * jnp.abs(coefficients[m]) * radius ** (m - order)
               for m in range(order, len(coefficients)))


class LinkMotion(NamedTuple):
    """One link over a piece ``|r - c| <= radius``: its end points and their first and second
    derivatives at c (cm, cm per unit r, cm per unit r squared; each of shape (...,)), and
    bounds on the second and third derivatives of any of its points over the piece."""

    near: tuple  # (x, y) of the end at the joint
    far: tuple  # (x, y) of the far end
    near_velocity: tuple
    far_velocity: tuple
    acceleration: jax.Array  # >= |X''(r)| for every point X of the link, |r - c| <= radius
    near_curvature: tuple  # the near end's second derivative at c
    far_curvature: tuple
    jerk: jax.Array  # >= |X^(3)(r)| for every point X of the link, |r - c| <= radius

    @classmethod
    def zeros(cls, like: jax.Array) -> "LinkMotion":
        """A motion of zeros shaped as ``like``."""
        zero = jnp.zeros_like(like)
        return cls((zero, zero), (zero, zero), (zero, zero), (zero, zero), zero, (zero, zero),
                   (zero, zero), zero)

    @property
    def top_speed(self) -> jax.Array:
        """The faster end point's speed at c: every point of the link moves no faster than
        (a point's velocity lies between its link's end points')."""
        return jnp.sqrt(jnp.maximum(sum(v * v for v in self.near_velocity),
                                    sum(v * v for v in self.far_velocity)))


def link_motions(lengths, about_centre: list, radius) -> list:
    """Every link's ``LinkMotion`` over a piece, from the joints' Taylor coefficients about
    its centre (``about_centre[m][j] = theta_j^(m)(c) / m!``).

    A point of link k at distance t along it is ``sum_{i<k} l_i u(phi_i) + t u(phi_k)``
    (``phi_i = theta_1 + ... + theta_i``), so ``|X''| <= sum_{i<=k} l_i (|phi_i''| +
    phi_i'^2)``, with bounds on ``|phi_i'|`` and ``|phi_i''|`` over the piece from its exact
    Taylor expansion; likewise ``|X^(3)| <= sum_{i<=k} l_i (|phi_i^(3)| + |phi_i'|^3 + 3
    |phi_i'| |phi_i''|)`` (``u(phi)^(3) = (phi^(3) - phi'^3) J u - 3 phi' phi'' u``).
    """
    lengths = jnp.asarray(lengths, dtype=about_centre[0][0].dtype)
    phi = [list(itertools.accumulate(order)) for order in about_centre]  # phi[m][i]
    x = y = vx = vy = ax = ay = jnp.zeros_like(about_centre[0][0])
    acceleration = jerk = 0.0
    motions = []
    for k in range(len(phi[0])):
        rate, turn, twist = (taylor_derivative_bound([order[k] for order in phi], radius, m)
                             for m in (1, 2, 3))
        acceleration = acceleration + lengths[k] * (turn + rate * rate)
        jerk = jerk + lengths[k] * (twist + rate * rate * rate + 3 * rate * turn)
        sine, cosine = sincos(phi[0][k])
        speed, bend = phi[1][k], 2 * phi[2][k]  # phi_k' and phi_k'' at c
        next_x, next_y = x + lengths[k] * cosine, y + lengths[k] * sine
        next_vx = vx - lengths[k] * speed * sine
        next_vy = vy + lengths[k] * speed * cosine
        next_ax = ax - lengths[k] * (bend * sine + speed * speed * cosine)
        next_ay = ay + lengths[k] * (bend * cosine - speed * speed * sine)
        motions.append(LinkMotion((x, y), (next_x, next_y), (vx, vy), (next_vx, next_vy),
                                  acceleration, (ax, ay), (next_ax, next_ay), jerk))
        x, y, vx, vy, ax, ay = next_x, next_y, next_vx, next_vy, next_ax, next_ay
    return motions


def drift_shortfalls(lengths, world, about_centre: list, radius, margin=0.0) -> list:
    """Per link, how far the piece ``|r - c| <= radius`` is from certified by two cheap bounds
    (cm; <= 0 proves the link clear): ``[min(s_k - (c_k - margin), e_k - (g_k - margin)) for
    each link k]``.

    - *Swing*: ``c_k`` is the cheaper bound of ``posture_clearance_bound`` at the centre,
      ``s_k = radius sum_{j<=k} M_j R_{jk}`` how far any point of link k can move (``M_j``
      bounds ``|theta_j'|`` there, from the exact Taylor expansion; ``reach_matrix``).
    - *Drift along each circle's axis*: the link moves as its linear part plus at most
      ``e_k = radius^2 / 2 * A_k`` (``sweep_shortfalls``), and the linear part stays in the
      hull of its end points moved by ``+/- radius`` times their velocities; ``g_k`` is the
      smallest of every circle's separation at the centre less how far that hull reaches
      towards it, along the axis from its centre through the link's nearest point
      (``world.circle_sweep_gaps``: a link sliding along a circle loses only its speed
      towards it, where the swing, a sum of magnitudes, loses all of it), and every polygon's
      gap at the centre less ``radius`` times the faster end's speed
      (``LinkMotion.top_speed``). Variants that cost more than they proved:
      ``benchmarks/RESULTS.md``, *Decisions and negative results*, "The window pass sees the
      direction of the motion".

    Cheaper than ``sweep_shortfalls`` (no axes of the hull's own edges), which the bisection
    then uses on what fails here.
    """
    speed = [taylor_derivative_bound([order[j] for order in about_centre], radius)
             for j in range(len(about_centre[0]))]
    swings = link_swings(lengths, speed, radius)
    shortfalls = []
    for k, motion in enumerate(link_motions(lengths, about_centre, radius)):
        link = (*motion.near, *motion.far)
        sweep = world_lib.Sweep(*(radius * v for v in motion.near_velocity + motion.far_velocity))
        circles, swept_circles = world_lib.circle_sweep_gaps(*link, sweep, world)
        polygons = world_lib.polygon_slots(*link, world, exact=False)
        none = jnp.full_like(link[0], jnp.inf)  # a world without obstacles
        clearance = _smallest(circles + polygons, none)
        spread = radius * motion.top_speed
        swept = _smallest(swept_circles + [gap - spread for gap in polygons], none)
        shortfalls.append(jnp.minimum(
            swings[k] - (clearance - margin),
            0.5 * radius * radius * motion.acceleration - (swept - margin)))
    return shortfalls


def sweep_shortfalls(lengths, world, about_centre: list, radius, margin=0.0) -> list:
    """Per link, how far the piece ``|r - c| <= radius`` is from certified by a second-order
    bound (cm): ``e_k - (h_k - margin)``, <= 0 proves link k clear of every obstacle there.

    Every point X of link k moves as ``X(c) + s X'(c) + E`` (``s = r - c``). The linear part
    of the whole link lies in the convex hull of its end points' four positions ``q(c) +/-
    radius q'(c)`` (a segment whose end points move linearly sweeps a bilinear patch, inside
    that hull), and ``|E| <= e_k = radius^2 / 2 * A_k`` (``LinkMotion``). So link k's
    signed distance to an obstacle (minus a penetration depth when they overlap) is at least
    ``h_k - e_k``, with ``h_k`` the hull's separating-axis gap (``hull_separation``: where the
    hull overlaps the obstacle it is at most minus the hull's penetration depth, which is at
    least the linear part's), or for the nearest circle and every polygon the better of that
    and how far the patch's turning line stays from it (``_Patch``): a link turning about a
    point beside an obstacle keeps its line's distance where its hull covers part of the
    obstacle. A path that grazes an obstacle, its distance ``c + a s^2`` near the closest
    approach, is proved with pieces of radius about ``sqrt(c / a)``: a few pieces where the
    first-order bound (``link_swings``) needs ``1 / sqrt(c)`` of them.

    In a world of circles alone a third-order bound counts too, the better of the two per
    circle: the link's quadratic part (its end points as ``q + s q' + s^2 / 2 q''``) lies in
    the hull of its ``bent_corners``, within ``radius^3 / 6 * J_k`` of the link
    (``LinkMotion.jerk``), and that hull is tested on the first hull's axes
    (``hull_separation``'s ``bent``). It has the exact curvature at the centre where the
    second-order remainder has a bound on the acceleration anywhere on the link and the piece.
    With polygons its dearer test ate what its fewer pieces saved: searches ran faster on some
    scenes and slower on others (``benchmarks/RESULTS.md``, *Decisions and negative results*,
    "A third-order bound in the bisection").

    Args:
      lengths, world: the problem's arrays.
      about_centre: ``about_centre[m][j] = theta_j^(m)(c) / m!`` for m = 0 .. degree, each
        of shape (...,).
      radius: the piece's half-width in r, a scalar or shape (...,).
      margin: the clearance to keep (cm).

    Returns:
      A list of n_joints arrays of shape (...,).
    """
    return motion_shortfalls(world, link_motions(lengths, about_centre, radius), radius, margin)


def motion_shortfalls(world, motions: list, radius, margin=0.0, separations=None) -> list:
    """``sweep_shortfalls`` of links given by their ``LinkMotion``s over the piece.

    ``separations``: optionally each link's ``world.separation_parts`` at the centre (the
    first-order bound's), else computed here: the nearest circle and the nearest polygon get
    separating axes, every other obstacle its distance less the hull's spread
    (``hull_separation``).
    """
    shortfalls = []
    for index, motion in enumerate(motions):
        (x, y), (next_x, next_y) = motion.near, motion.far
        (vx, vy), (next_vx, next_vy) = motion.near_velocity, motion.far_velocity
        parts = (world_lib.separation_parts(x, y, next_x, next_y, world) if separations is None
                 else separations[index])
        # the hull lies within this distance of the link at the centre (``top_speed``)
        spread = radius * motion.top_speed
        patch = _Patch((x, y), (next_x, next_y), (radius * vx, radius * vy),
                       (radius * next_vx, radius * next_vy))
        second = 0.5 * radius * radius * motion.acceleration
        bent = None
        if not world.vertices.shape[0]:  # circles alone: the third-order bound too
            bent = (bent_corners(motion, radius), radius ** 3 / 6 * motion.jerk - second)
        hull = hull_separation(
            world, patch.corners(), circle_distances=(parts.circles, spread), patch=patch,
            polygon_distances=None if parts.polygons is None else (parts.polygons, spread),
            bent=bent)
        shortfalls.append(second - (hull - margin))
    return shortfalls


def bent_corners(motion: LinkMotion, radius) -> list:
    """Six points whose convex hull holds the link's quadratic part over the piece: each end
    point as ``q + s q' + s^2 / 2 q''`` (``|s| <= radius``) is an arc inside the triangle of
    its Bezier control points ``q +/- radius q' + radius^2 / 2 q''`` and ``q - radius^2 / 2
    q''``, and the link's points are convex combinations of its ends. Ordered as
    ``_Patch.corners`` (the two chords' ends), then the two apexes."""
    half = 0.5 * radius * radius

    def triangle(end, velocity, curvature):  # (chord start, chord end, apex)
        (x, y), (vx, vy), (ax, ay) = end, velocity, curvature
        return ((x - radius * vx + half * ax, y - radius * vy + half * ay),
                (x + radius * vx + half * ax, y + radius * vy + half * ay),
                (x - half * ax, y - half * ay))
    near_start, near_end, near_apex = triangle(motion.near, motion.near_velocity,
                                               motion.near_curvature)
    far_start, far_end, far_apex = triangle(motion.far, motion.far_velocity,
                                            motion.far_curvature)
    return [near_start, near_end, far_end, far_start, near_apex, far_apex]


_CORNER_PAIRS = tuple(itertools.combinations(range(4), 2))  # every hull edge is one of them


@rank_promotion_allowed
def hull_separation(world, corners: list, circle_distances=None, patch=None,
                    polygon_distances=None, bent=None):
    """A lower bound on the signed distance from the convex hull of points to the nearest
    obstacle (cm; negative where they may overlap: at most minus the penetration depth);
    +inf without obstacles.

    The largest gap between the projections of the hull and of an obstacle on a few axes
    (separating axes): the normals of the six segments between the first four corners (with
    four corners, every hull edge is one of them), for circles the axis from the centre
    through the nearest corner (with it, a circle's gap is its exact distance from the hull
    when apart), and for polygons their edge normals. A gap on any axis is at
    most the distance (where the sets overlap, every axis's overlap is at least the smallest
    translation that parts them), and on the axis normal to the hull edge facing an obstacle
    it is the distance: the case of a link sweeping past an obstacle. Near a corner of both it
    can be less. It is cheaper than the hull's exact distance, which takes six segments'
    distances and a test for an obstacle inside the hull.

    Args:
      corners: at least four ``(x, y)`` pairs, each coordinate of shape (...,).
      circle_distances: optional ``(distances, spread)``: every circle slot's distance from
        a set within ``spread`` of every point of the hull (``world.circle_slots``; each of
        shape (...,)). Then only the nearest circle by that distance gets separating axes;
        every other circle's gap is its distance less ``spread`` (a lower bound, cheaper).
      patch: optional ``_Patch`` whose sweep the hull holds: then the bound is on the
        patch's distance, each tested circle's and polygon's gap the better of the hull's and
        the patch's turning line's (``_line_gap``).
      polygon_distances: optional ``(distances, spread)`` as ``circle_distances``, for the
        polygon slots (``world.separation_parts(...).polygons``, shape (n_polygon_slots,
        ...)): only the nearest polygon gets separating axes and the turning line.
      bent: optional ``(corners, allowance)``: a second hull, tested against circles on the
        same axes and its own nearest corner's; each tested circle's gap is then the better of
        the first hull's and the second's less ``allowance`` (shape (...,)). Polygons get the
        first hull's gap alone.

    Returns:
      Array of shape (...,).
    """
    dtype = corners[0][0].dtype
    axes, bent_axes = [], []  # (nx, ny, the hull's lowest and highest projection on the axis)
    for i, j in _CORNER_PAIRS:
        nx, ny = world_lib.unit_normal(*corners[i], *corners[j])
        axes.append((nx, ny, *_projection_range(nx, ny, corners)))
        if bent is not None:
            bent_axes.append((nx, ny, *_projection_range(nx, ny, bent[0])))
    nearest = jnp.full(corners[0][0].shape, jnp.inf, dtype)
    circles = jnp.asarray(world.circles, dtype)

    def circle_gap(px, py, radius):
        gaps = [_circle_gap(px, py, radius, axes, corners)]
        if bent is not None:
            gaps.append(_circle_gap(px, py, radius, bent_axes, bent[0]) - bent[1])
        if patch is not None:
            gaps.append(_line_gap(*patch.line_sides(px, py), patch.longest) - radius)
        return functools.reduce(jnp.maximum, gaps)
    if circle_distances is not None and circles.shape[0] > 1:
        distances, spread = circle_distances
        picked, closest, others = _nearest_slot(distances, [circles[:, c] for c in range(3)])
        nearest = jnp.minimum(  # empty slots have distance inf: none nearest if all are
            jnp.where(closest < jnp.inf, circle_gap(*picked), jnp.inf),
            others - spread)
    else:
        for i in range(circles.shape[0]):
            gap = circle_gap(circles[i, 0], circles[i, 1], circles[i, 2])
            nearest = jnp.minimum(nearest, jnp.where(world.circle_valid[i], gap, jnp.inf))
    n_polygons, n_vertices = world.vertices.shape[:2]
    if n_polygons:
        per_vertex = [jnp.asarray(a, dtype)[:, v] for a in (
            world.vertices[..., 0], world.vertices[..., 1], world.normals[..., 0],
            world.normals[..., 1], world.extent_low, world.extent_high)
            for v in range(n_vertices)] + [world.edge_valid[:, v] for v in range(n_vertices)]
        if polygon_distances is not None and n_polygons > 1:
            distances, spread = polygon_distances
            picked, closest, others = _nearest_slot(list(distances), per_vertex)
            gap = _polygon_gap(picked, n_vertices, axes, corners, patch)
            nearest = jnp.minimum(nearest, jnp.minimum(
                jnp.where(closest < jnp.inf, gap, jnp.inf), others - spread))
        else:
            slots = functools.partial(world_lib.leading_slots, ndim=corners[0][0].ndim)
            gap = _polygon_gap([slots(a) for a in per_vertex], n_vertices, axes, corners, patch)
            nearest = jnp.minimum(nearest, jnp.where(slots(world.polygon_valid), gap,
                                                     jnp.inf).min(axis=0))
    return nearest


def _nearest_slot(distances: list, fields: list) -> tuple:
    """The obstacle slot nearest by ``distances`` (one array per slot), picked slot by slot (a
    stacked argmin compiled to a scalar loop): ``(picked, closest, others)``, ``picked[f]``
    field f (``fields[f]``, shape (n_slots,)) of that slot, ``closest`` its distance and
    ``others`` the least of the other slots' (each of the distances' shape)."""
    picked = [field[0] for field in fields]
    closest, others = distances[0], jnp.full_like(distances[0], jnp.inf)
    for i in range(1, len(distances)):
        nearer = distances[i] < closest
        picked = [jnp.where(nearer, field[i], p) for field, p in zip(fields, picked)]
        others = jnp.minimum(others, jnp.maximum(closest, distances[i]))
        closest = jnp.minimum(closest, distances[i])
    return picked, closest, others


def _polygon_gap(per_vertex: list, n_vertices: int, axes: list, corners: list, patch):
    """The separating-axis gap between the hull of ``corners`` (on its ``axes``) and polygons
    given vertex by vertex (``per_vertex``: x, y, normal x, normal y, low extent, high extent,
    edge valid, each a list of ``n_vertices`` arrays that broadcast against the corners),
    with the better of it and ``patch``'s turning line when given."""
    xs, ys, normal_xs, normal_ys, lows, highs, valid = (
        per_vertex[i * n_vertices:(i + 1) * n_vertices] for i in range(7))
    gap = None
    for v in range(n_vertices):  # the polygons' edge normals
        low, high = _projection_range(normal_xs[v], normal_ys[v], corners)
        edge_gap = jnp.where(valid[v], jnp.maximum(low - highs[v], lows[v] - high), -jnp.inf)
        gap = edge_gap if gap is None else jnp.maximum(gap, edge_gap)
    for nx, ny, low, high in axes:  # the hull's
        along = [nx * x + ny * y for x, y in zip(xs, ys)]
        lowest, highest = _valid_range(along, along, valid)
        gap = jnp.maximum(gap, jnp.maximum(lowest - high, low - highest))
    if patch is not None:  # every vertex on one side of the link's turning line
        sides = [patch.line_sides(x, y) for x, y in zip(xs, ys)]
        below, above = _valid_range([side[0] for side in sides], [side[1] for side in sides],
                                    valid)
        gap = jnp.maximum(gap, _line_gap(below, above, patch.longest))
    return gap


def _valid_range(lows: list, highs: list, valid: list) -> tuple:
    """The least of ``lows`` and the greatest of ``highs`` over a polygon's valid vertices
    (one array per vertex, ``valid`` its edge mask): ``(inf, -inf)`` where none is valid."""
    return (functools.reduce(jnp.minimum, [jnp.where(ok, a, jnp.inf)
                                           for a, ok in zip(lows, valid)]),
            functools.reduce(jnp.maximum, [jnp.where(ok, a, -jnp.inf)
                                           for a, ok in zip(highs, valid)]))


def _circle_gap(px, py, radius, axes: list, corners: list):
    """The separating-axis gap between a circle and the hull of ``corners`` on the hull's
    ``axes`` and on the axis from the circle's centre through the nearest corner: with the
    hull's edges among the axes, the circle's exact distance from the hull when apart."""
    gaps = [jnp.maximum(nx * px + ny * py - high, low - (nx * px + ny * py))
            for nx, ny, low, high in axes]
    offsets = [(cx - px, cy - py) for cx, cy in corners]
    squared = [dx * dx + dy * dy for dx, dy in offsets]
    nx, ny = offsets[0]
    closest = squared[0]
    for (dx, dy), d2 in zip(offsets[1:], squared[1:]):
        nearer = d2 < closest
        nx, ny, closest = (jnp.where(nearer, dx, nx), jnp.where(nearer, dy, ny),
                           jnp.minimum(d2, closest))
    # a corner at the centre (no axis): the hull holds the centre, no gap on this axis
    length = jnp.sqrt(jnp.maximum(closest, jnp.finfo(closest.dtype).tiny))
    gaps.append(jnp.where(closest > 0, functools.reduce(
        jnp.minimum, [nx * dx + ny * dy for dx, dy in offsets]) / length, -jnp.inf))
    return functools.reduce(jnp.maximum, gaps) - radius


class _Patch(NamedTuple):
    """A segment whose end points move linearly, ``near + t near_step`` and ``far + t
    far_step`` for ``|t| <= 1`` (each a pair of coordinates of shape (...,)): the bilinear patch
    a link's linear part sweeps over a piece (``sweep_shortfalls``)."""

    near: tuple
    far: tuple
    near_step: tuple
    far_step: tuple

    def corners(self) -> list:
        """The end points at t = -1 and 1, whose convex hull holds the patch: four (x, y)."""
        (ax, ay), (bx, by) = self.near, self.far
        (sax, say), (sbx, sby) = self.near_step, self.far_step
        return [(ax - sax, ay - say), (ax + sax, ay + say), (bx + sbx, by + sby),
                (bx - sbx, by - sby)]

    @property
    def longest(self) -> jax.Array:
        """A bound on ``|D(t)|`` over ``|t| <= 1`` (``line_sides``): convex in t, so largest
        at an end."""
        (ax, ay), (bx, by) = self.near, self.far
        (sax, say), (sbx, sby) = self.near_step, self.far_step
        dx, dy, ex, ey = bx - ax, by - ay, sbx - sax, sby - say
        return jnp.sqrt(jnp.maximum((dx - ex) ** 2 + (dy - ey) ** 2,
                                    (dx + ex) ** 2 + (dy + ey) ** 2))

    def line_sides(self, px, py) -> tuple:
        """The least and greatest of ``N(t) = D(t) x (p - near(t))`` over ``|t| <= 1``, exact
        (``D(t) = far(t) - near(t)``; ``N(t) / |D(t)|`` is p's signed distance from the
        segment's line): ``(lowest, highest)``."""
        (ax, ay), (bx, by) = self.near, self.far
        (sax, say), (sbx, sby) = self.near_step, self.far_step
        dx, dy, ex, ey = bx - ax, by - ay, sbx - sax, sby - say
        qx, qy = px - ax, py - ay
        n0 = dx * qy - dy * qx
        n1 = (ex * qy - ey * qx) - (dx * say - dy * sax)
        n2 = -(ex * say - ey * sax)  # N(t) = n0 + n1 t + n2 t^2
        ends_low = jnp.minimum(n0 - n1 + n2, n0 + n1 + n2)
        ends_high = jnp.maximum(n0 - n1 + n2, n0 + n1 + n2)
        inside = jnp.abs(n1) < 2 * jnp.abs(n2)  # the vertex t = -n1 / (2 n2) in (-1, 1)
        vertex = n0 - n1 * n1 / (4 * jnp.where(inside, n2, 1.0))
        lowest = jnp.where(inside & (n2 > 0), jnp.minimum(ends_low, vertex), ends_low)
        highest = jnp.where(inside & (n2 < 0), jnp.maximum(ends_high, vertex), ends_high)
        return lowest, highest


def _line_gap(lowest, highest, longest):
    """The distance every ``N(t) / |D(t)|`` keeps from zero on one side (``_Patch.line_sides``,
    ``longest`` its ``_Patch.longest``): a lower bound on the distance from the patch to the
    points whose sides these are, when all are on one side at every t; -inf otherwise."""
    side = jnp.maximum(lowest, -highest)
    return jnp.where(side > 0, side / longest, -jnp.inf)


def _projection_range(nx, ny, points: list) -> tuple:
    """The lowest and highest projection of ``points`` ((x, y) pairs) on the axis (nx, ny)."""
    along = [nx * x + ny * y for x, y in points]
    return functools.reduce(jnp.minimum, along), functools.reduce(jnp.maximum, along)
