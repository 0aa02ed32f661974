"""Geometry against an independent oracle, shapely.

Obstacles are open sets (grazing contact is not a collision), which is shapely's
``relate_pattern(segment, obstacle, "T********")``: the interiors intersect.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely

import jaxarm
from jaxarm import collision, path
from jaxarm import world as world_lib

CAPACITIES = (4, 8, 8)


def random_world(rng) -> jaxarm.World:
    circles = [(*rng.uniform(-60, 60, 2), rng.uniform(1, 12)) for _ in range(rng.integers(0, 4))]
    boxes = []
    for _ in range(rng.integers(0, 4)):
        low = rng.uniform(-60, 50, 2)
        boxes.append((tuple(low), tuple(low + rng.uniform(0.5, 25, 2))))
    polygons = []
    for _ in range(rng.integers(0, 4)):
        points = rng.uniform(-15, 15, (rng.integers(3, 9), 2)) + rng.uniform(-50, 50, 2)
        hull = shapely.MultiPoint(points).convex_hull
        if hull.geom_type == "Polygon" and hull.area > 1.0:
            vertices = np.asarray(hull.exterior.coords)[:-1]
            polygons.append(vertices[::-1] if rng.random() < 0.5 else vertices)
    return jaxarm.World(circles=circles, boxes=boxes, polygons=polygons)


def shapely_obstacles(world: jaxarm.World):
    """Circles as (center, radius) for exact distances; boxes and polygons as Polygons."""
    polygons = [shapely.box(*lo, *hi) for lo, hi in world.boxes]
    polygons += [shapely.Polygon(p) for p in world.polygons]
    return [(shapely.Point(c[:2]), c[2]) for c in world.circles], polygons


def oracle_separation(world, start, end):
    """Signed separation of each segment from the nearest obstacle, and the open-set verdict."""
    circles, polygons = shapely_obstacles(world)
    segments = shapely.linestrings(np.stack([start, end], axis=-2))
    distance = np.full(len(segments), np.inf)
    hit = np.zeros(len(segments), dtype=bool)
    for center, radius in circles:
        d = shapely.distance(segments, center) - radius
        distance, hit = np.minimum(distance, d), hit | (d < 0)
    for polygon in polygons:
        distance = np.minimum(distance, shapely.distance(segments, polygon))
        hit |= shapely.relate_pattern(segments, polygon, "T********")
    return distance, hit


def test_segment_separation_agrees_with_shapely_on_random_worlds(rng):
    checked = 0
    for _ in range(300):
        world = random_world(rng)
        start = rng.uniform(-70, 70, (40, 2))
        end = start + rng.normal(0, 20, (40, 2))
        packed = world.pack(CAPACITIES)
        separation = np.asarray(world_lib.separation(jnp.asarray(start), jnp.asarray(end),
                                                     packed)).min(axis=-1)
        penetration = np.asarray(world_lib.penetration(jnp.asarray(start), jnp.asarray(end),
                                                       packed)).sum(axis=-1)
        distance, hit = oracle_separation(world, start, end)
        clear = np.abs(separation) > 1e-3  # away from exact tangency (float32 rounding)
        np.testing.assert_array_equal((penetration > 0)[clear], hit[clear])
        np.testing.assert_array_equal((separation < 0)[clear], hit[clear])
        apart = clear & ~hit
        np.testing.assert_allclose(separation[apart], distance[apart], rtol=1e-4, atol=1e-3)
        # The certified check's cheap bound: never above the distance, and zero-crossing where
        # the exact separation does (its negative part is the same penetration depth).
        bound = np.asarray(world_lib.separation_bound_xy(
            *(jnp.asarray(a) for a in (start[:, 0], start[:, 1], end[:, 0], end[:, 1])),
            packed)).min(axis=0)
        assert np.all(bound[apart] <= distance[apart] + 1e-3)
        np.testing.assert_array_equal((bound < 0)[clear], hit[clear])
        checked += clear.sum()
    assert checked > 10_000


@pytest.mark.parametrize("offset, collides", [(0.5, True), (-0.5, False), (0.0, False)])
def test_segment_parallel_to_a_box_side(offset, collides):
    """Paper-case-1 has horizontal last links (exactly zero dy) next to a box's bottom side."""
    world = jaxarm.World(boxes=[((33.0, 0.0), (70.0, 30.0))])
    start = jnp.array([[20.0, offset], [40.0, offset]])
    end = jnp.array([[40.0, offset], [50.0, offset]])
    penetration = np.asarray(world_lib.penetration(start, end, world.pack()))
    assert (penetration[1].sum() > 0) == collides
    _, hit = oracle_separation(world, np.asarray(start), np.asarray(end))
    assert hit[1] == collides


def _paths_world_problems(rng, n_worlds):
    """Problems with random worlds around a fixed start and goal (skipping colliding ones)."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    problems = []
    while len(problems) < n_worlds:
        try:
            problems.append(jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                           world=random_world(rng), capacities=CAPACITIES,
                                           init_low=-60.0, init_high=60.0))
        except ValueError:
            continue
    return problems


def _positions(problem, x, n_samples):
    r = np.linspace(0.0, 1.0, n_samples)
    theta = jaxarm.joint_path(problem, x, r)
    return np.asarray(jaxarm.joint_positions(problem.arm.lengths, theta), dtype=np.float64)


def _oracle_path_collides(problem, x, n_samples):
    """Per path: does any link's interior meet any obstacle's at any of n_samples samples."""
    positions = _positions(problem, x, n_samples)  # (paths, samples, joints + 1, 2)
    start, end = positions[..., :-1, :], positions[..., 1:, :]
    _, hit = oracle_separation(problem.world, start.reshape(-1, 2), end.reshape(-1, 2))
    return hit.reshape(len(x), -1).any(axis=-1)


def test_sampled_check_agrees_with_shapely_on_the_same_samples(rng):
    agreed = 0
    for problem in _paths_world_problems(rng, 40):
        x = rng.uniform(problem.init_low, problem.init_high, (25, problem.n_free))
        ours = np.asarray(jaxarm.violation(problem, x))
        oracle = _oracle_path_collides(problem, x, problem.n_samples)
        decided = (ours == 0) | (ours > 1e-4)  # skip paths that only graze an obstacle
        np.testing.assert_array_equal((ours > 0)[decided], oracle[decided])
        agreed += decided.sum()
    assert agreed > 900


def thin_wall_problem(rng):
    """A 0.2 cm wall somewhere in the arm's way: what a sampled check can step over."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    while True:
        corner = rng.uniform(-50, 50, 2)
        size = (0.2, rng.uniform(5, 30)) if rng.random() < 0.5 else (rng.uniform(5, 30), 0.2)
        world = jaxarm.World(boxes=[(tuple(corner), tuple(corner + size))],
                             circles=[(*rng.uniform(-60, 60, 2), rng.uniform(1, 5))])
        try:
            return jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                  world=world, capacities=CAPACITIES)
        except ValueError:
            continue


def test_certified_is_sound_and_not_too_conservative_against_a_dense_check(rng):
    certified_free = sampled_free = certified_of_dense_free = dense_free = 0
    missed_by_sampling = 0
    for _ in range(30):
        problem = thin_wall_problem(rng).replace(collision="sampled")
        certified = problem.replace(collision="certified")
        x = rng.uniform(-60, 60, (200, problem.n_free))
        sampled_ok = np.asarray(jaxarm.violation(problem, x)) == 0
        certified_ok = np.asarray(jaxarm.violation(certified, x)) == 0
        assert not np.any(certified_ok & ~sampled_ok)
        candidates = np.nonzero(sampled_ok)[0][:10]  # dense checks are the expensive part
        if candidates.size == 0:
            continue
        dense_ok = ~_oracle_path_collides(problem, x[candidates], 10_001)
        # Soundness: nothing certified collides anywhere along the dense check.
        assert not np.any(certified_ok[candidates] & ~dense_ok)
        missed_by_sampling += np.sum(~dense_ok)
        certified_free += certified_ok.sum()
        sampled_free += sampled_ok.sum()
        dense_free += dense_ok.sum()
        certified_of_dense_free += np.sum(certified_ok[candidates] & dense_ok)
    assert missed_by_sampling > 0, "expected the sampled check to step over some thin walls"
    assert dense_free > 60
    # Not so conservative that it rejects most free motions.
    assert certified_of_dense_free / dense_free > 0.6, (certified_of_dense_free, dense_free)


@pytest.mark.parametrize("degree", [6, 8])
def test_window_speed_bounds_hold_on_a_dense_grid(rng, degree):
    """The window pass's bound on |theta_j'| over a window (centre velocity plus Taylor tail
    weights) is never below the true speed."""
    n_samples = 21
    step = 1.0 / (n_samples - 1)
    start, goal = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3)
    x = rng.uniform(-200, 200, (50, 3 * (degree - 5)))
    samples = np.linspace(0.0, 1.0, n_samples)
    with jax.enable_x64(True):
        window_tails = collision.tail_weights(degree, samples, step / 2)
        worst_ratio = 0.0
        for s in range(n_samples):
            centre, radius = samples[s], step / 2
            velocity = path.joint_angle_list(start, goal, jnp.asarray(x),
                                             path.basis_values(degree, [centre], 1), order=1)
            bound = collision.speed_bound(start, goal, jnp.asarray(x),
                                          [v[:, 0] for v in velocity],
                                          jnp.asarray(window_tails[s]))
            dense = np.linspace(centre - radius, centre + radius, 41)
            true = path.joint_angles(start, goal, jnp.asarray(x),
                                     path.basis_values(degree, dense, 1), order=1)
            true = np.abs(np.asarray(true)).max(axis=1)  # (paths, joints)
            bound = np.stack([np.asarray(b) for b in bound], axis=-1)
            assert np.all(true <= bound * (1 + 1e-12)), s
            worst_ratio = max(worst_ratio, float((true / bound).max()))
    assert worst_ratio > 0.9  # and not uselessly loose
