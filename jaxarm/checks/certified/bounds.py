"""Bounds on a link's distance to the obstacles over a piece ``|r - c| <= radius`` of a path,
from the joints' Taylor coefficients about the centre c: what the certified check's windows
(``drift_shortfalls``) and bisection (``link_swings``, ``sweep_shortfalls``) prove with.

- First order (``link_swings``): how far any point of a link can move over the piece.
- Second order (``sweep_shortfalls``): the link's linear motion (its end points moved along
  their velocities) against the obstacles (``hull``), less a bound on the acceleration term;
  in a world of circles alone, a third order (``bent_corners``) too.

A shortfall is how far a piece is from proved: <= 0 proves the link keeps the margin there.
For an arm that checks self-collision, the lists go on with one more shortfall, the largest
over the pairs of links (``jaxarm.model.self_collision``): each later link against the earlier
one, in its frame.
"""

from __future__ import annotations

import functools
import itertools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.checks import collision as collision_lib
from jaxarm.checks.certified.hull import Patch, hull_separation
from jaxarm.model import self_collision
from jaxarm.model import world as world_lib
from jaxarm.model.arm import sincos


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
    link k]`` (``reach_matrix``). A link whose clearance at c
    (``collision.link_clearance_bounds``) less the margin is at least its swing is clear over
    the piece: the first-order bound.

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

    - *Swing*: ``c_k`` is the cheaper bound of ``collision.posture_clearance_bound`` at the
      centre, ``s_k = radius sum_{j<=k} M_j R_{jk}`` how far any point of link k can move (``M_j``
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
        spread = radius * motion.top_speed

        def gaps(world, per_link):
            link, sweep, spread = per_link
            circles, swept_circles = world_lib.circle_sweep_gaps(*link, sweep, world)
            polygons = world_lib.polygon_slots(*link, world, exact=False)
            none = jnp.full_like(link[0], jnp.inf)  # a world without obstacles
            return (functools.reduce(jnp.minimum, circles + polygons, none),
                    functools.reduce(jnp.minimum,
                                     swept_circles + [gap - spread for gap in polygons], none))
        if world.near is None:
            clearance, swept = gaps(world, (link, sweep, spread))
        else:  # the listed obstacles, and the reach for the others (``near_minimum``)
            clearance, swept = collision_lib.near_minimum(world, k, link, gaps,
                                                          (link, sweep, spread))
            swept = jnp.minimum(swept, jnp.asarray(world.near.reach, swept.dtype) - spread)
        shortfalls.append(jnp.minimum(
            swings[k] - (clearance - margin),
            0.5 * radius * radius * motion.acceleration - (swept - margin)))
    return shortfalls + _pair_shortfalls(drift_shortfalls, lengths, world, about_centre, radius,
                                         margin)


def _pair_shortfalls(shortfalls_of, lengths, world, about_centre: list, radius, margin) -> list:
    """``shortfalls_of``'s bound for the pairs of links of an arm that checks self-collision
    (``self_collision.over_pairs``: each later link against the earlier one as a wall, moving
    as it moves relative to it), as one entry: the largest over the pairs; none otherwise."""
    if world.link_walls is None:
        return []
    rows, real = self_collision.over_pairs(
        lengths, world.link_walls, about_centre,
        lambda lengths, wall, joints: shortfalls_of(lengths, wall, joints, radius, margin))
    return [self_collision.only_real(rows, real, -jnp.inf).max(axis=0)]


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
    and how far the patch's turning line stays from it (``hull.Patch``): a link turning about a
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
    With polygons its dearer test did not pay for its fewer pieces (see
    ``benchmarks/RESULTS.md``, *Decisions and negative results*, "A third-order bound in the
    bisection").

    Args:
      lengths, world: the problem's arrays.
      about_centre: ``about_centre[m][j] = theta_j^(m)(c) / m!`` for m = 0 .. degree, each
        of shape (...,).
      radius: the piece's half-width in r, a scalar or shape (...,).
      margin: the clearance to keep (cm).

    Returns:
      A list of n_joints arrays of shape (...,) (and the pairs', module docstring).
    """
    return (motion_shortfalls(world, link_motions(lengths, about_centre, radius), radius, margin)
            + _pair_shortfalls(sweep_shortfalls, lengths, world, about_centre, radius, margin))


def motion_shortfalls(world, motions: list, radius, margin=0.0, separations=None) -> list:
    """``sweep_shortfalls`` of links given by their ``LinkMotion``s over the piece.

    ``separations``: optionally each link's ``world.separation_parts`` at the centre (the
    first-order bound's), else computed here: the nearest circle and the nearest polygon get
    separating axes, every other obstacle its distance less the hull's spread
    (``hull_separation``).
    """
    shortfalls = []
    for index, motion in enumerate(motions):
        second = 0.5 * radius * radius * motion.acceleration
        hull = motion_gap(world, motion, radius, second,
                          None if separations is None else separations[index])
        shortfalls.append(second - (hull - margin))
    return shortfalls


def motion_gap(world, motion: LinkMotion, radius, second, parts=None):
    """A lower bound on the separating-axis gap between the hull of a link's linear part over
    the piece and every obstacle (``motion_shortfalls``' ``h_k``), from the link's
    ``world.separation_parts`` at the centre (``parts``; computed here if None)."""
    (x, y), (next_x, next_y) = motion.near, motion.far
    (vx, vy), (next_vx, next_vy) = motion.near_velocity, motion.far_velocity
    parts = world_lib.separation_parts(x, y, next_x, next_y, world) if parts is None else parts
    # the hull lies within this distance of the link at the centre (``top_speed``)
    spread = radius * motion.top_speed
    patch = Patch((x, y), (next_x, next_y), (radius * vx, radius * vy),
                  (radius * next_vx, radius * next_vy))
    bent = None
    if not world.vertices.shape[0]:  # circles alone: the third-order bound too
        bent = (bent_corners(motion, radius), radius ** 3 / 6 * motion.jerk - second)
    return hull_separation(
        world, patch.corners(), circle_distances=(parts.circles, spread), patch=patch,
        polygon_distances=None if parts.polygons is None else (parts.polygons, spread),
        bent=bent)


def tight_bounds(world, swing, motion: LinkMotion, radius, margin, n_joints: int):
    """The bisection's bounds on rows of links (a leading axis: (rows, n) each): the arm's
    n_joints links against ``world``, then, for an arm that checks self-collision, the pairs'
    rows (``self_collision.over_pairs``) each against its frame's wall. Returns the first-order
    and second-order shortfalls and the centre's clearance, (rows, n) each; padding rows
    -inf, -inf and +inf."""
    arm = rows_against(world, swing[:n_joints], jax.tree.map(lambda v: v[:n_joints], motion),
                       radius, margin)
    if world.link_walls is None:
        return arm

    def per_frame(rows):  # (n_frames, n_joints - 2, n)
        return rows[n_joints:].reshape((n_joints - 2, n_joints - 2) + rows.shape[1:])
    frames = jax.vmap(lambda wall, swing, motion: rows_against(wall, swing, motion, radius,
                                                               margin))(
        world.link_walls, per_frame(swing), jax.tree.map(per_frame, motion))
    real = self_collision.real_rows(n_joints)
    pairs = [self_collision.only_real(bound.reshape((-1,) + bound.shape[2:]), real, fill)
             for bound, fill in zip(frames, (-jnp.inf, -jnp.inf, jnp.inf))]
    return tuple(jnp.concatenate(values) for values in zip(arm, pairs))


def rows_against(world, swing, motion: LinkMotion, radius, margin):
    """The first-order and second-order shortfalls and the centre's clearance of rows of
    links (a leading axis: (rows, n) each) against ``world`` over pieces of ``radius``
    (shape (n,)): ``link_swings`` against the nearest obstacle, ``motion_gap``."""
    second = 0.5 * radius[None] * radius[None] * motion.acceleration

    def gaps(world, per_link):  # the nearest obstacle at the centre and the hull's gap
        motion, radius, second = per_link
        parts = world_lib.separation_parts(*motion.near, *motion.far, world)
        return (collision_lib.smallest_separation(parts, second),  # second: the links' shape
                motion_gap(world, motion, radius, second, parts))
    if world.near is None:
        clearance, hull = gaps(world, (motion, radius[None], second))
    else:  # each link's listed obstacles, the reach for the others
        links = jnp.arange(swing.shape[0])[:, None]
        clearance, hull = collision_lib.near_minimum(
            world, links, (*motion.near, *motion.far), gaps, (motion, radius[None], second))
        reach = jnp.asarray(world.near.reach, swing.dtype)
        hull = jnp.minimum(hull, reach - radius[None] * motion.top_speed)
    return swing - (clearance - margin), second - (hull - margin), clearance


def bent_corners(motion: LinkMotion, radius) -> list:
    """Six points whose convex hull holds the link's quadratic part over the piece: each end
    point as ``q + s q' + s^2 / 2 q''`` (``|s| <= radius``) is an arc inside the triangle of
    its Bezier control points ``q +/- radius q' + radius^2 / 2 q''`` and ``q - radius^2 / 2
    q''``, and the link's points are convex combinations of its ends. Ordered as
    ``hull.Patch.corners`` (the two chords' ends), then the two apexes."""
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
