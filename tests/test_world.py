"""Obstacles and segment-obstacle separation (``jaxarm.model.world``) against shapely."""

import jax.numpy as jnp
import numpy as np
import pytest
from random_worlds import CAPACITIES, random_world

import jaxarm
from jaxarm._compile.jit import jit  # compiles faster than jax.jit on CPU
from jaxarm.model import world as world_lib
from jaxarm.testing import oracle_separation


def _on_end_points(kernel, start, end, world):
    """An ``*_xy`` kernel of ``world`` applied to segments given by end points of shape
    (..., 2): shape (..., n_slots), the obstacle slots last."""
    coordinates = (start[..., 0], start[..., 1], end[..., 0], end[..., 1])
    return jnp.moveaxis(kernel(*coordinates, world), 0, -1)


def segment_separation(start, end, world):
    """``world.separation_xy`` of segments given by end points: shape (..., n_slots)."""
    return _on_end_points(world_lib.separation_xy, start, end, world)


def segment_overlap_depth(start, end, world):
    """``world.overlap_depth_xy`` of segments given by end points: shape (..., n_slots)."""
    return _on_end_points(world_lib.overlap_depth_xy, start, end, world)


@pytest.mark.parametrize(
    "world, message",
    [
        (dict(circles=[(0.0, 0.0)]), r"world.circles\[0\] must have 3 values"),
        (dict(boxes=[((1.0, 1.0), (0.0, 2.0))]), r"world.boxes\[0\] needs min < max"),
        (dict(polygons=[[(0, 0), (1, 1), (2, 2)]]), r"world.polygons\[0\] is degenerate"),
        (dict(polygons=[[(0, 0), (1, 0)]]), r"world.polygons\[0\] must be at least 3"),
        (dict(circles=[(0.0, 1e300, 1.0)]),
         r"world.circles\[0\].center\[1\] must be within \+-100000 cm, got 1e\+300"),
        (dict(circles=[(0.0, 50.0, 1e-40)]), r"world.circles\[0\].radius must be 0 or at least"),
        (dict(boxes=[((0.0, 0.0), (2e5, 1.0))]), r"world.boxes\[0\].max\[0\] must be within"),
        (dict(polygons=[[(0, 0), (1e39, 0), (0, 1)]]),
         r"world.polygons\[0\].vertices\[1\]\[0\] must be within \+-100000 cm"),
        (dict(segments=[((0, 0), (1, 1), (2, 2))]),
         r"world.segments\[0\] must be two points \(\(x0, y0\), \(x1, y1\)\)"),
        (dict(segments=[((1.0, 2.0), (1.0, 2.0))]), r"world.segments\[0\] needs two distinct"),
        (dict(segments=[((0, 0), (float("nan"), 1))]), r"world.segments\[0\] points must be fin"),
        (dict(segments=[((0, 0), (3e5, 1))]), r"world.segments\[0\].points\[1\]\[0\] must be"),
    ],
)
def test_bad_worlds(world, message):
    with pytest.raises(ValueError, match=message):
        jaxarm.World(**world)


def test_segment_separation_agrees_with_shapely_on_random_worlds(rng):
    # compiled once (op by op, 300 worlds took most of this test's time), as jaxarm compiles
    separation_of, depth_of, bound_of = (jit(f) for f in (
        segment_separation, segment_overlap_depth, world_lib.separation_bound_xy))
    # The sampled check computes polygons slot by slot: the same numbers as the array form.
    slot_forms = jit(lambda *args: [jnp.stack(world_lib.polygon_slots(*args, exact=exact))
                                    for exact in (True, False)])
    array_forms = jit(lambda *args: [world_lib.polygon_separation_xy(*args),
                                     world_lib.polygon_overlap_gap_xy(*args),
                                     world_lib.polygon_separation_xy(*args, vertex_axis=True)])
    checked = 0
    for _ in range(300):
        world = random_world(rng)
        start = rng.uniform(-70, 70, (40, 2))
        end = start + rng.normal(0, 20, (40, 2))
        packed = world.pack(CAPACITIES)
        separation = np.asarray(separation_of(jnp.asarray(start), jnp.asarray(end),
                                              packed)).min(axis=-1)
        depth = np.asarray(depth_of(jnp.asarray(start), jnp.asarray(end), packed)).sum(axis=-1)
        distance, hit = oracle_separation(world, start, end)
        clear = np.abs(separation) > 1e-3  # away from exact tangency (float32 rounding)
        np.testing.assert_array_equal((depth > 0)[clear], hit[clear])
        np.testing.assert_array_equal((separation < 0)[clear], hit[clear])
        apart = clear & ~hit
        np.testing.assert_allclose(separation[apart], distance[apart], rtol=1e-4, atol=1e-3)
        # The certified check's cheap bound: never above the distance, and zero-crossing where
        # the exact separation does (its negative part is the same penetration depth).
        bound = np.asarray(bound_of(
            *(jnp.asarray(a) for a in (start[:, 0], start[:, 1], end[:, 0], end[:, 1])),
            packed)).min(axis=0)
        assert np.all(bound[apart] <= distance[apart] + 1e-3)
        np.testing.assert_array_equal((bound < 0)[clear], hit[clear])
        coordinates = [jnp.asarray(a) for a in (start[:, 0], start[:, 1], end[:, 0], end[:, 1])]
        exact, gap, vertex_axis = array_forms(*coordinates, packed)
        for by_slot, as_array in zip(slot_forms(*coordinates, packed), (exact, gap)):
            np.testing.assert_allclose(by_slot, as_array, rtol=1e-6, atol=1e-5)
        # The certified check's pieces take the vertex slots as an axis: the same numbers up to
        # how XLA rounds each edge's distance (the same bits on jax 0.10.2; up to 2 ulps apart
        # in 255 of 34,080 values on jax 0.8.0, make test-oldest).
        np.testing.assert_allclose(vertex_axis, exact, rtol=1e-6, atol=1e-5)
        checked += clear.sum()
    assert checked > 10_000


@pytest.mark.parametrize("offset, collides", [(0.5, True), (-0.5, False), (0.0, False)])
def test_segment_parallel_to_a_box_side(offset, collides):
    """Paper-case-1 has horizontal last links (exactly zero dy) next to a box's bottom side."""
    world = jaxarm.World(boxes=[((33.0, 0.0), (70.0, 30.0))])
    start = jnp.array([[20.0, offset], [40.0, offset]])
    end = jnp.array([[40.0, offset], [50.0, offset]])
    depth = np.asarray(segment_overlap_depth(start, end, world.pack()))
    assert (depth[1].sum() > 0) == collides
    _, hit = oracle_separation(world, np.asarray(start), np.asarray(end))
    assert hit[1] == collides


@pytest.mark.parametrize("end, depth", [
    ((5.0, 3.0), 3.0),  # crosses the wall: 3 cm from clearing it along the wall's normal
    ((9.5, -10.0), 0.0),  # touches its end point alone: open sets, no penetration
    ((5.0, -0.5), 0.0),  # stops short of it: its distance
])
def test_a_segment_is_a_wall_of_zero_thickness(end, depth):
    """A link from (5, -4) against the wall from (0, 0) to (10, 0): crossing it penetrates by
    the nearer of the link's ends beyond the wall's line or the wall's ends beyond the
    link's; grazing it does not; apart, the distance."""
    world = jaxarm.World(segments=[((0.0, 0.0), (10.0, 0.0))])
    start = np.array([[5.0, -4.0]]) if end != (9.5, -10.0) else np.array([[10.0, 0.0]])
    separation = float(segment_separation(jnp.asarray(start), jnp.asarray([end]),
                                          world.pack())[0, 0])
    distance, hit = oracle_separation(world, start, np.array([end]))
    assert hit[0] == (depth > 0)
    assert separation == pytest.approx(-depth if depth > 0 else max(float(distance[0]), 0.0),
                                       abs=1e-5)
    assert world.obstacle_name(0) == "segments[0]" and world.capacities() == (0, 1, 2)


def test_a_segment_on_the_links_own_line_is_apart_by_its_distance():
    """Collinear and apart: no separating axis among the two normals, yet not touching (a
    straight arm's links, each in the frame of an earlier one, lie so)."""
    world = jaxarm.World(segments=[((0.0, 0.0), (10.0, 0.0))])
    start, end = jnp.array([[20.0, 0.0], [10.0, 0.0]]), jnp.array([[30.0, 0.0], [15.0, 0.0]])
    separation = np.asarray(segment_separation(start, end, world.pack()))[:, 0]
    np.testing.assert_allclose(separation, [10.0, 0.0], atol=1e-6)  # apart; touching its end
