"""Separating-axis gaps between the convex hull of a few points and the obstacles: a lower
bound on the distance of whatever the hull holds (a link's motion over a piece, ``bounds``),
cheaper than the hull's exact distance.

``hull_separation`` tests the hull's edge normals, each circle's axis through the nearest
corner and each polygon's edge normals; ``Patch`` adds how far a link's turning line stays
from an obstacle, for a link turning about a point beside one.
"""

from __future__ import annotations

import functools
import itertools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm._compile.jit import rank_promotion_allowed
from jaxarm.model import world as world_lib


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
      patch: optional ``Patch`` whose sweep the hull holds: then the bound is on the
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
            world.vertices[:, :, 0], world.vertices[:, :, 1], world.normals[:, :, 0],
            world.normals[:, :, 1], world.extent_low, world.extent_high)
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


class Patch(NamedTuple):
    """A segment whose end points move linearly, ``near + t near_step`` and ``far + t
    far_step`` for ``|t| <= 1`` (each a pair of coordinates of shape (...,)): the bilinear patch
    a link's linear part sweeps over a piece (``bounds.sweep_shortfalls``)."""

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
    """The distance every ``N(t) / |D(t)|`` keeps from zero on one side (``Patch.line_sides``,
    ``longest`` its ``Patch.longest``): a lower bound on the distance from the patch to the
    points whose sides these are, when all are on one side at every t; -inf otherwise."""
    side = jnp.maximum(lowest, -highest)
    return jnp.where(side > 0, side / longest, -jnp.inf)


def _projection_range(nx, ny, points: list) -> tuple:
    """The lowest and highest projection of ``points`` ((x, y) pairs) on the axis (nx, ny)."""
    along = [nx * x + ny * y for x, y in points]
    return functools.reduce(jnp.minimum, along), functools.reduce(jnp.maximum, along)
