"""Obstacle worlds: circles, axis-aligned boxes, convex polygons and segments, packed as data.

A ``World`` is validated once and packed into fixed-capacity arrays with validity masks
(``WorldArrays``), so a new obstacle layout with the same capacities reuses compiled code.
Boxes become 4-vertex polygons and segments (walls of zero thickness) 2-vertex ones, whose
two edges run both ways along the wall. Obstacles are open sets: a link that only grazes an
obstacle's boundary (zero penetration) does not collide, so "collision-free" and "zero
penetration" agree. A link that crosses a segment penetrates it: by the smaller distance it
would have to move along either axis, the wall's normal or its own, to clear it.

Geometry kernel: the signed separation between a segment and each obstacle, positive (the
Euclidean distance) when disjoint and minus the penetration depth when they overlap.
For a circle it is ``dist(center, segment) - radius``. For a convex polygon, overlap is decided
by the separating axis theorem over the polygon's edge normals and the segment's normal; the
largest axis gap is minus the penetration depth when they overlap, and the exact distance
(point-to-segment distances between the two boundaries) is used when they are apart.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import rank_promotion_allowed
from jaxarm._validate import MAX_CM, finite_vector, representable

_TINY = 1e-30


class WorldArrays(NamedTuple):
    """Obstacles packed into fixed capacities (a pytree of arrays; no recompilation per layout)."""

    circles: jnp.ndarray  # shape=(n_circle_slots, 3), float: x, y, radius
    circle_valid: jnp.ndarray  # shape=(n_circle_slots,), bool
    vertices: jnp.ndarray  # shape=(n_polygon_slots, n_vertex_slots, 2), counter-clockwise
    normals: jnp.ndarray  # shape=(n_polygon_slots, n_vertex_slots, 2), outward unit edge normals
    extent_low: jnp.ndarray  # shape=(n_polygon_slots, n_vertex_slots), min of polygon . normal
    extent_high: jnp.ndarray  # shape=(n_polygon_slots, n_vertex_slots), max of polygon . normal
    edge_valid: jnp.ndarray  # shape=(n_polygon_slots, n_vertex_slots), bool
    polygon_valid: jnp.ndarray  # shape=(n_polygon_slots,), bool
    # The broad phase's ``jaxarm.model.nearby.NearTables`` of a large world for its arm (None:
    # every slot is tested; ``Problem.arrays`` sets it).
    near: object = None
    # An arm that checks self-collision: its links 0 .. n - 3 as walls in their own frames,
    # stacked on a leading axis (``jaxarm.model.self_collision``; None: not checked;
    # ``Problem.arrays`` sets it).
    link_walls: object = None


# The WorldArrays fields with one entry per circle slot, and per polygon slot.
CIRCLE_FIELDS = ("circles", "circle_valid")
POLYGON_FIELDS = ("vertices", "normals", "extent_low", "extent_high", "edge_valid",
                  "polygon_valid")


OBSTACLE_KINDS = ("circles", "boxes", "polygons", "segments")  # ``World``'s order


def slot_capacity(count: int) -> int:
    """0 for none (the kernel for that shape is skipped), else the smallest power of two >=
    count: layouts of similar size share one program (the added obstacles of
    ``benchmarks/blocking.py``)."""
    return 0 if count == 0 else 1 << (count - 1).bit_length()


@dataclasses.dataclass(frozen=True)
class World:
    """Obstacles in the plane (cm).

    Args:
      circles: ``(x, y, radius)`` triples, radius > 0.
      boxes: ``((xmin, ymin), (xmax, ymax))`` pairs with min < max on both axes.
      polygons: convex polygons, each a list of >= 3 ``(x, y)`` vertices in either order.
      segments: walls of zero thickness, ``((x0, y0), (x1, y1))`` pairs of distinct points.

    Examples:
      >>> world = jaxarm.World(circles=[(40.0, 4.5, 6.7)], boxes=[((10.0, -5.0), (20.0, 5.0))])
      >>> world.n_obstacles
      2
    """

    circles: tuple = ()
    boxes: tuple = ()
    polygons: tuple = ()
    segments: tuple = ()

    def __post_init__(self):
        for kind, check in (("circles", check_circle), ("boxes", check_box),
                            ("polygons", check_polygon), ("segments", check_segment)):
            object.__setattr__(self, kind, tuple(
                check(f"world.{kind}[{i}]", value) for i, value in enumerate(getattr(self, kind))))

    @property
    def n_obstacles(self) -> int:
        return sum(len(getattr(self, kind)) for kind in OBSTACLE_KINDS)

    def polygon_vertices(self) -> list[np.ndarray]:
        """Boxes, polygons (counter-clockwise) then segments as vertex arrays, each shape
        (n_vertices, 2): a polygon slot each."""
        out = []
        for (xmin, ymin), (xmax, ymax) in self.boxes:
            out.append(np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]]))
        for polygon in self.polygons:
            vertices = np.asarray(polygon, dtype=np.float64)
            if _signed_area(vertices) < 0:
                vertices = vertices[::-1]
            out.append(vertices)
        out += [np.asarray(segment, dtype=np.float64) for segment in self.segments]
        return out

    def capacities(self) -> tuple[int, int, int]:
        """Default (circle, polygon, vertex) slot counts: the world's own (vertices: its largest
        polygon's, 4 without polygons). Padded slots are computed like full ones, so the default
        pads none (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Exact
        capacities by default"); ``jaxarm.share_capacities`` pads scenes to share a program."""
        polygons = self.polygon_vertices()
        return (len(self.circles), len(polygons),
                max((len(p) for p in polygons), default=4))

    def obstacle_name(self, index: int) -> str:
        """The name of obstacle ``index`` in ``World``'s order (circles, boxes, polygons,
        segments): ``"boxes[2]"``."""
        for kind in OBSTACLE_KINDS:
            count = len(getattr(self, kind))
            if 0 <= index < count:
                return f"{kind}[{index}]"
            index -= count
        raise ValueError(f"obstacle index must be in [0, {self.n_obstacles}), got {index!r}")

    def slot_names(self, capacities: tuple[int, int, int]) -> list[str | None]:
        """Obstacle name of every slot of a packing (circle slots, then polygon slots)."""
        n_circle_slots, n_polygon_slots, _ = capacities
        circles = [f"circles[{i}]" for i in range(len(self.circles))]
        polygons = [f"{kind}[{i}]" for kind in OBSTACLE_KINDS[1:]
                    for i in range(len(getattr(self, kind)))]
        pad = lambda names, n: names + [None] * (n - len(names))  # noqa: E731
        return pad(circles, n_circle_slots) + pad(polygons, n_polygon_slots)

    def pack(self, capacities: tuple[int, int, int] | None = None) -> WorldArrays:
        """Pack into fixed-capacity float64 NumPy arrays with validity masks.

        Args:
          capacities: (circle slots, polygon slots, vertex slots); default ``capacities()``.
        """
        n_circle_slots, n_polygon_slots, n_vertex_slots = capacities or self.capacities()
        polygons = self.polygon_vertices()
        if len(self.circles) > n_circle_slots or len(polygons) > n_polygon_slots:
            raise ValueError(
                f"capacities {capacities} too small for {len(self.circles)} circles and "
                f"{len(polygons)} boxes, polygons and segments"
            )
        circles = np.zeros((n_circle_slots, 3))
        circles[:, :2], circles[:, 2] = 1e4, 1.0  # unused slots, far away and masked
        circles[: len(self.circles)] = np.asarray(self.circles, dtype=np.float64).reshape(-1, 3)
        circle_valid = np.arange(n_circle_slots) < len(self.circles)

        vertices = np.zeros((n_polygon_slots, n_vertex_slots, 2))
        # Unused slots: a harmless shape far from any arm (masked out in every kernel).
        vertices[:, :, 0] = 1e4 + np.arange(n_vertex_slots)
        vertices[:, :, 1] = 1e4
        edge_valid = np.zeros((n_polygon_slots, n_vertex_slots), dtype=bool)
        for index, polygon in enumerate(polygons):
            if len(polygon) > n_vertex_slots:
                raise ValueError(
                    f"capacities {capacities}: {len(polygon)} vertices exceed {n_vertex_slots}"
                )
            # Padding repeats the first vertex: padded edges have zero length (masked) and the
            # closing edge (last vertex -> first) comes out of the same roll as the others.
            vertices[index] = polygon[0]
            vertices[index, : len(polygon)] = polygon
            edge_valid[index, : len(polygon)] = True
        polygon_valid = np.arange(n_polygon_slots) < len(polygons)
        edge_valid &= polygon_valid[:, None]

        edges = np.roll(vertices, -1, axis=1) - vertices
        lengths = np.linalg.norm(edges, axis=-1, keepdims=True)
        normals = np.stack([edges[..., 1], -edges[..., 0]], axis=-1) / np.maximum(lengths, _TINY)
        projections = np.einsum("pvd,pwd->pvw", normals, vertices)  # normal v . vertex w
        return WorldArrays(
            circles=circles,
            circle_valid=circle_valid,
            vertices=vertices,
            normals=normals,
            extent_low=projections.min(axis=-1),
            extent_high=projections.max(axis=-1),
            edge_valid=edge_valid,
            polygon_valid=polygon_valid,
        )


def _signed_area(vertices: np.ndarray) -> float:
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def check_circle(field: str, circle) -> tuple[float, float, float]:
    """``(x, y, r)`` as floats, or a ValueError naming ``field`` (e.g. ``"world.circles[3]"``)."""
    values = finite_vector(field, circle, length=3)
    if values[2] <= 0:
        raise ValueError(f"{field} radius must be > 0, got {float(values[2])!r}")
    representable(f"{field}.center", values[:2], MAX_CM, " cm")
    representable(f"{field}.radius", values[2], MAX_CM, " cm")
    return tuple(float(v) for v in values)


def check_box(field: str, box) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((xmin, ymin), (xmax, ymax))`` as floats, or a ValueError naming ``field``."""
    try:
        low, high = box
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be ((xmin, ymin), (xmax, ymax)), got {box!r}") from None
    low = representable(f"{field}.min", finite_vector(f"{field}.min", low, length=2), MAX_CM,
                        " cm")
    high = representable(f"{field}.max", finite_vector(f"{field}.max", high, length=2), MAX_CM,
                         " cm")
    if not np.all(low < high):
        raise ValueError(f"{field} needs min < max on both axes, got min {low} max {high}")
    return (float(low[0]), float(low[1])), (float(high[0]), float(high[1]))


def check_polygon(field: str, polygon) -> tuple[tuple[float, float], ...]:
    """Convex vertices as float pairs, or a ValueError naming ``field``."""
    try:
        vertices = np.asarray(polygon, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a list of (x, y) vertices, got {polygon!r}") from None
    if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
        raise ValueError(f"{field} must be at least 3 (x, y) vertices, got {polygon!r}")
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"{field} vertices must be finite, got {polygon!r}")
    representable(f"{field}.vertices", vertices, MAX_CM, " cm")
    edges = np.roll(vertices, -1, axis=0) - vertices
    turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    scale = np.max(np.abs(vertices)) + 1.0
    if np.any(np.abs(turns) <= 1e-12 * scale**2):
        raise ValueError(f"{field} is degenerate (repeated or collinear vertices): {polygon!r}")
    if not (np.all(turns > 0) or np.all(turns < 0)):
        raise ValueError(f"{field} is not convex: {polygon!r}")
    total_turn = np.sum(np.arctan2(turns, np.sum(edges * np.roll(edges, -1, axis=0), axis=1)))
    if abs(abs(total_turn) - 2 * np.pi) > 1e-6:
        raise ValueError(f"{field} is not a simple convex polygon (it winds twice): {polygon!r}")
    return tuple((float(x), float(y)) for x, y in vertices)


def check_segment(field: str, segment) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((x0, y0), (x1, y1))`` as floats, two distinct points, or a ValueError naming
    ``field``."""
    try:
        points = np.asarray(segment, dtype=np.float64)
    except (TypeError, ValueError):
        points = None
    if points is None or points.shape != (2, 2):
        raise ValueError(f"{field} must be two points ((x0, y0), (x1, y1)), got {segment!r}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{field} points must be finite, got {segment!r}")
    representable(f"{field}.points", points, MAX_CM, " cm")
    if np.all(points[0] == points[1]):
        raise ValueError(f"{field} needs two distinct points, got {segment!r}")
    return tuple((float(x), float(y)) for x, y in points)


def leading_slots(values, ndim: int):
    """Obstacle data of shape (n_slots,) as (n_slots, 1, ..., 1) to broadcast against (...).

    Slots lead so that the innermost axis stays the caller's (the samples): elementwise loops
    then vectorise over it instead of over a handful of obstacle slots. Data already of shape
    (n_slots, ...) (a block of listed slots per link, ``jaxarm.model.nearby.block_world``) is
    returned as it is.
    """
    if values.ndim > 1:
        return values
    return values.reshape(values.shape[:1] + (1,) * ndim)


def _from_segment(px, py, ax, ay, bx, by):
    """The vector from the nearest point of segments (a, b) to points (px, py)."""
    dx, dy = bx - ax, by - ay
    t = ((px - ax) * dx + (py - ay) * dy) / jnp.maximum(dx * dx + dy * dy, _TINY)
    t = jnp.clip(t, 0.0, 1.0)
    return px - ax - t * dx, py - ay - t * dy


def point_segment_distance(px, py, ax, ay, bx, by):
    """Distance from points (px, py) to segments (a, b); all arguments broadcast together."""
    ox, oy = _from_segment(px, py, ax, ay, bx, by)
    # The floor keeps the gradient finite where a point lies on the segment (e.g. a link's
    # base on an obstacle vertex): sqrt'(0) is infinite and 0 * inf would poison masked slots.
    return jnp.sqrt(jnp.maximum(ox * ox + oy * oy, _TINY))


class Sweep(NamedTuple):
    """How far a segment's end points move: the start anywhere on ``s +/- (ux, uy)``, the end
    on ``e +/- (wx, wy)``, each coordinate of shape (...); the moving segment stays inside
    the convex hull of those four points (a segment moving linearly, over an interval of r
    about its centre, in ``jaxarm.checks.certified.bounds``)."""

    ux: jax.Array
    uy: jax.Array
    wx: jax.Array
    wy: jax.Array


def circle_sweep_gaps(sx, sy, ex, ey, sweep: Sweep, world: WorldArrays) -> tuple[list, list]:
    """Every circle slot's signed separation from a segment at rest (as ``circle_slots``), and
    a lower bound on its separation from the sweep's hull: the separation less how far the
    hull reaches towards the circle along the axis from its centre through the segment's
    nearest point (the end points' larger move along it). A segment moving along a circle's
    edge loses only its speed towards the centre. Two lists of one array of the coordinates'
    shape (...) per slot, +inf for empty slots."""
    circles = jnp.asarray(world.circles, dtype=sx.dtype)
    at_rest, swept = [], []
    for i in range(circles.shape[0]):
        px, py, radius = circles[i, 0], circles[i, 1], circles[i, 2]
        ox, oy = _from_segment(px, py, sx, sy, ex, ey)
        squared = jnp.maximum(ox * ox + oy * oy, _TINY)
        inverse = jax.lax.rsqrt(squared)
        separation = squared * inverse - radius
        reach = jnp.maximum(jnp.abs(sweep.ux * ox + sweep.uy * oy),
                            jnp.abs(sweep.wx * ox + sweep.wy * oy)) * inverse
        at_rest.append(jnp.where(world.circle_valid[i], separation, jnp.inf))
        swept.append(jnp.where(world.circle_valid[i], separation - reach, jnp.inf))
    return at_rest, swept


def circle_slots(sx, sy, ex, ey, world: WorldArrays) -> list:
    """Signed separation of segments from every circle slot (distance minus radius; +inf for
    empty slots), one array of the coordinates' shape (...) per slot.

    Written out slot by slot with each circle's numbers as scalars: with the slots as a leading
    array axis, the reduction over them compiled to a scalar loop on CPU
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Polygons slot by slot in the
    sampled check").
    """
    circles = jnp.asarray(world.circles, dtype=sx.dtype)
    return [jnp.where(world.circle_valid[i],
                      point_segment_distance(circles[i, 0], circles[i, 1], sx, sy, ex, ey)
                      - circles[i, 2], jnp.inf)
            for i in range(circles.shape[0])]


def circle_separation_xy(sx, sy, ex, ey, world: WorldArrays):
    """``circle_slots`` stacked: shape (n_circle_slots, ...)."""
    slots = circle_slots(sx, sy, ex, ey, world)
    return jnp.stack(slots) if slots else jnp.zeros((0,) + sx.shape, sx.dtype)


@rank_promotion_allowed
def polygon_overlap_gap_xy(sx, sy, ex, ey, world: WorldArrays):
    """Largest separating-axis gap between segments and every polygon slot: a lower bound on
    their distance when positive, minus the penetration depth otherwise; +inf for empty slots.
    Coordinates of shape (...); returns shape (n_polygon_slots, ...).

    The polygon slots stay an array axis here (unlike ``circle_slots``): written out per slot
    and per vertex, the certified check of a world with many polygon slots took far longer to
    compile. The sampled check, and the certified check's samples and windows, call it one
    slot at a time (``polygon_slots``).

    The obstacle data, shape (n_slots, 1, ..., 1), meet the coordinates by NumPy's rank
    promotion. With the coordinates' leading axis made explicit the values were the same, but
    the compiled gradient of refine's surrogate on death-trap no longer matched the one
    computed op by op (tests/test_polish.py): the gap is a maximum of pieces, and rounding
    picks one at near-ties."""
    dtype, n = sx.dtype, sx.ndim
    # Written out per coordinate and per vertex slot (a static, small count): contractions and
    # reductions over axes of length 2 or 4 compile to slow loops on CPU, while this form
    # fuses into one vectorised elementwise loop.
    mx, my = unit_normal(sx, sy, ex, ey)
    offset = mx * sx + my * sy
    normals = jnp.asarray(world.normals, dtype=dtype)
    vertices = jnp.asarray(world.vertices, dtype=dtype)
    low = jnp.asarray(world.extent_low, dtype=dtype)
    high = jnp.asarray(world.extent_high, dtype=dtype)
    gap = jnp.full((normals.shape[0],) + sx.shape, -jnp.inf, dtype)
    along_min = along_max = None
    for v in range(normals.shape[1]):
        nx, ny = leading_slots(normals[:, v, 0], n), leading_slots(normals[:, v, 1], n)
        a = sx * nx + sy * ny
        b = ex * nx + ey * ny
        edge_gap = jnp.maximum(jnp.minimum(a, b) - leading_slots(high[:, v], n),
                               leading_slots(low[:, v], n) - jnp.maximum(a, b))
        gap = jnp.maximum(gap, jnp.where(leading_slots(world.edge_valid[:, v], n), edge_gap, -jnp.inf))
        along = mx * leading_slots(vertices[:, v, 0], n) + my * leading_slots(vertices[:, v, 1], n)
        along_min = along if along_min is None else jnp.minimum(along_min, along)
        along_max = along if along_max is None else jnp.maximum(along_max, along)
    gap = jnp.maximum(gap, jnp.maximum(along_min - offset, offset - along_max))
    return jnp.where(leading_slots(world.polygon_valid, n), gap, jnp.inf)


def unit_normal(sx, sy, ex, ey):
    """The unit normal ``(-dy, dx) / length`` of segments (s, e), about 0 for a segment of
    length 0; all arguments broadcast together."""
    dx, dy = ex - sx, ey - sy
    inverse_length = jax.lax.rsqrt(jnp.maximum(dx * dx + dy * dy, _TINY))
    return -dy * inverse_length, dx * inverse_length


def _edge_distance(sx, sy, ex, ey, vx, vy, wx, wy, valid):
    """Distance between segments (s, e) and polygon edges (v, w), +inf from the segments'
    end points to invalid edges; all arguments broadcast together."""
    to_edge = jnp.minimum(
        point_segment_distance(sx, sy, vx, vy, wx, wy),
        point_segment_distance(ex, ey, vx, vy, wx, wy),
    )
    to_edge = jnp.where(valid, to_edge, jnp.inf)
    from_vertex = point_segment_distance(vx, vy, sx, sy, ex, ey)
    return jnp.minimum(to_edge, from_vertex)


@rank_promotion_allowed
def polygon_separation_xy(sx, sy, ex, ey, world: WorldArrays, vertex_axis: bool = False):
    """Signed separation between segments and every polygon slot: the exact distance when
    disjoint, minus the penetration depth when overlapping, +inf for empty slots.
    Coordinates of shape (...); returns shape (n_polygon_slots, ...).

    ``vertex_axis``: the distances to the edges as one array with the vertex slots as an axis
    rather than written out per vertex: the same values up to how XLA rounds an edge's
    distance in each program (a minimum is exact), a few float32 ulps on some jax versions
    (tests/test_world.py's random worlds). It compiles to fewer kernels, so the certified
    check compiles faster ("Fewer kernels in the certified check" in
    ``benchmarks/RESULTS.md``, *Decisions and negative results*); the sampled check with a
    margin keeps the written-out form, which runs faster there."""
    n = sx.ndim
    gap = polygon_overlap_gap_xy(sx, sy, ex, ey, world)
    vertices = jnp.asarray(world.vertices, dtype=sx.dtype)
    following = jnp.roll(vertices, -1, axis=1)
    if vertex_axis:
        def slots_and_vertices(a):  # (n_slots, n_vertices) as (n_slots, n_vertices, 1, ..., 1)
            return a if a.ndim > 2 else a.reshape(a.shape[:2] + (1,) * n)

        distance = _edge_distance(
            sx, sy, ex, ey, *(slots_and_vertices(a[:, :, i]) for a in (vertices, following)
                              for i in (0, 1)),
            slots_and_vertices(world.edge_valid)).min(axis=1)
    else:
        distance = jnp.full(gap.shape, jnp.inf, gap.dtype)
        for v in range(vertices.shape[1]):  # static and small: see polygon_overlap_gap_xy
            distance = jnp.minimum(distance, _edge_distance(
                sx, sy, ex, ey, *(leading_slots(a[:, v, i], n) for a in (vertices, following)
                                  for i in (0, 1)),
                leading_slots(world.edge_valid[:, v], n)))
    # A segment (two edges) on the link's own line, apart from it, has no separating axis
    # here (both normals give 0): its gap 0 is no contact, and its distance is the separation.
    apart = (gap > 0) | ((gap == 0) & leading_slots(world.edge_valid.sum(axis=1) == 2, n))
    signed = jnp.where(apart, distance, gap)
    return jnp.where(leading_slots(world.polygon_valid, n), signed, jnp.inf)


class SeparationParts(NamedTuple):
    """Signed separations of segments of shape (...) from every obstacle, in two parts."""

    circles: list  # one array of shape (...) per circle slot (``circle_slots``)
    polygons: jax.Array | None  # shape (n_polygon_slots, ...); None without polygon slots


def separation_parts(sx, sy, ex, ey, world: WorldArrays) -> SeparationParts:
    """Exact signed separation of segments from every obstacle (+inf for empty slots), the
    polygons with their vertex slots as an axis (the certified check tests a few pieces at a
    time with them).

    Args:
      sx, sy, ex, ey: segment end points, each of shape (...).
    """
    return SeparationParts(
        circles=circle_slots(sx, sy, ex, ey, world),
        polygons=(polygon_separation_xy(sx, sy, ex, ey, world, vertex_axis=True)
                  if world.vertices.shape[0] else None))


def polygon_slots(sx, sy, ex, ey, world: WorldArrays, *, exact: bool) -> list:
    """Signed separation of segments from every polygon slot (+inf for empty slots), computed
    slot by slot: one array of the coordinates' shape (...) per slot. ``exact``: the exact
    separation (``polygon_separation_xy``), or the separating-axis gap
    (``polygon_overlap_gap_xy``: at most the distance, exact where <= 0).

    Like ``separation_parts(...).polygons`` unstacked, but each slot is computed alone (as a
    world of one polygon). The sampled check and the certified check's samples and windows use
    it: with the polygon slots as an array axis, XLA compiled the sampled check into slow loops
    whenever there were 2 or more slots, and the certified check's samples and windows ran far
    slower on polygon scenes. The certified bisection's exact distances keep the array form:
    written out slot by slot, its program took far longer to compile (``benchmarks/RESULTS.md``,
    *Decisions and negative results*, "Polygons slot by slot in the sampled check" and
    "Polygons slot by slot in the certified check's samples and windows").
    """
    polygon = polygon_separation_xy if exact else polygon_overlap_gap_xy
    return [polygon(sx, sy, ex, ey, one_polygon(world, k))[0]
            for k in range(world.vertices.shape[0])]


def _map_polygon_slots(world: WorldArrays, change) -> WorldArrays:
    """The world with ``change`` applied to each per-polygon-slot array (slots first)."""
    return world._replace(**{name: change(getattr(world, name)) for name in POLYGON_FIELDS})


def one_polygon(world: WorldArrays, slot: int) -> WorldArrays:
    """Polygon slot ``slot`` of the world alone, as a world with one polygon slot and no
    circles."""
    alone = _map_polygon_slots(world, lambda a: a[slot:slot + 1])
    return alone._replace(circles=world.circles[:0], circle_valid=world.circle_valid[:0])


def separation_xy(sx, sy, ex, ey, world: WorldArrays):
    """Signed separation between segments and every obstacle slot (circles, then polygons;
    +inf for empty slots). Coordinates of shape (...); returns shape (n_slots, ...)."""
    return jnp.concatenate(
        [circle_separation_xy(sx, sy, ex, ey, world),
         polygon_separation_xy(sx, sy, ex, ey, world)],
        axis=0,
    )


def separation_bound_xy(sx, sy, ex, ey, world: WorldArrays):
    """A cheap lower bound on ``separation_xy``, exact wherever it is <= 0; shape (n_slots, ...).

    Circles give their exact separation and polygons their separating-axis gap, which is minus
    the penetration depth when overlapping and at most the distance when apart (for a box at
    least 1/sqrt(2) of it). The certified check only needs a lower bound on the distance.
    """
    return jnp.concatenate([circle_separation_xy(sx, sy, ex, ey, world),
                            polygon_overlap_gap_xy(sx, sy, ex, ey, world)], axis=0)


def overlap_depth_xy(sx, sy, ex, ey, world: WorldArrays):
    """How deep segments overlap every obstacle slot (their penetration depth; 0 for empty
    slots), >= 0 and zero iff no overlap. Coordinates of shape (...); returns shape (n_slots,
    ...). Cheaper than ``separation_xy`` (no distances for disjoint polygons)."""
    return jnp.maximum(-separation_bound_xy(sx, sy, ex, ey, world), 0.0)
