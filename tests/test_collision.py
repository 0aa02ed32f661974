"""The sampled check (``jaxarm.checks.collision``) and the certified check's bounds
(``jaxarm.checks.certified.bounds`` and ``hull``) against shapely and dense grids."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import shapely
from random_worlds import random_world_problems

import jaxarm
from jaxarm.checks import collision
from jaxarm.checks.certified import bounds, hull
from jaxarm.model import path
from jaxarm.model.arm import link_endpoints
from jaxarm.model import world as world_lib
from jaxarm.testing import (
    link_segments,
    oracle_path_collides,
    oracle_separation,
    shapely_obstacles,
)


def test_sampled_check_agrees_with_shapely_on_the_same_samples(rng):
    agreed = 0
    for problem in random_world_problems(rng, 40, collision="sampled"):
        x = rng.uniform(problem.init_low, problem.init_high, (25, problem.n_free))
        ours = np.asarray(jaxarm.violation(problem, x))
        oracle = oracle_path_collides(problem, x, problem.n_samples)
        decided = (ours == 0) | (ours > 1e-4)  # skip paths that only graze an obstacle
        np.testing.assert_array_equal((ours > 0)[decided], oracle[decided])
        agreed += decided.sum()
    assert agreed > 900


@pytest.mark.parametrize("name", ["mixed-clutter", "polygon-field"])
def test_sampled_check_with_a_margin_agrees_with_shapely_distances(rng, name):
    """Exact distances (a margin): the violation is the deepest sample's sum, over links and
    obstacles, of how far each link is inside the margin. polygon-field, padded to 4 polygon
    slots of 8 vertices, has more link-edge pairs than ``collision.UNROLLED_LINK_EDGES`` (its
    links are taken one at a time), mixed-clutter fewer."""
    margin = 2.0
    problem = jaxarm.load_scenario(name, collision="sampled").replace(margin=margin,
                                                                       n_samples=21)
    if name == "polygon-field":
        problem = problem.replace(capacities=(0, 4, 8))
    pairs = collision.link_edge_pairs(len(problem.arm.lengths), problem.arrays.world)
    assert (pairs > collision.UNROLLED_LINK_EDGES) == (name == "polygon-field")
    x = rng.uniform(problem.init_low, problem.init_high, (300, problem.n_free))
    segments = link_segments(problem, x, problem.n_samples)  # (paths, samples, links, 2, 2)
    lines = shapely.linestrings(segments.reshape(-1, 2, 2))
    circles, polygons = shapely_obstacles(problem.world)
    distance = np.stack([shapely.distance(lines, centre) - radius for centre, radius in circles]
                        + [shapely.distance(lines, polygon) for polygon in polygons], axis=-1)
    distance = distance.reshape(*segments.shape[:3], -1)
    inside = np.maximum(margin - distance, 0).sum(axis=(2, 3)).max(axis=1)
    overlap = (distance <= 0).any(axis=(1, 2, 3))  # shapely: 0 inside a polygon, no depth
    ours = np.asarray(jaxarm.violation(problem, x))
    np.testing.assert_allclose(ours[~overlap], inside[~overlap], atol=2e-4)
    assert np.all(ours[overlap] > 0)
    # most random paths cross an obstacle: 9 (mixed-clutter) and 15 (polygon-field) come within
    # the margin without touching one, 34 and 46 stay clear of it
    assert np.sum(~overlap & (inside > 0)) >= 5 and np.sum(inside == 0) >= 20


def test_violation_is_the_deepest_penetration_found_at_a_sample(rng):
    """Circles only, where shapely's distances give depths: sampled, the depths summed over
    links and circles at a sample, the deepest sample; certified (a path colliding at a
    sample), the nearest link's depth at the deepest sample."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    checked = 0
    for _ in range(6):
        world = jaxarm.World(circles=[(*rng.uniform(-50, 50, 2), rng.uniform(3, 12))
                                      for _ in range(3)])
        try:
            problem = jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                     world=world, init_low=-60.0, init_high=60.0)
        except ValueError:
            continue
        x = rng.uniform(-60, 60, (30, problem.n_free))
        segments = link_segments(problem, x, problem.n_samples)  # (paths, samples, links, 2, 2)
        lines = shapely.linestrings(segments.reshape(-1, 2, 2))
        depth = np.stack([np.maximum(radius - shapely.distance(lines, shapely.Point(cx, cy)), 0)
                          for cx, cy, radius in world.circles], axis=-1)
        depth = depth.reshape(*segments.shape[:3], -1)  # (paths, samples, links, circles)
        sampled = np.asarray(jaxarm.violation(problem.replace(collision="sampled"), x))
        np.testing.assert_allclose(sampled, depth.sum(axis=(2, 3)).max(axis=1), atol=2e-4)
        hit = depth.max(axis=(1, 2, 3)) > 1e-3
        certified = np.asarray(jaxarm.violation(problem.replace(collision="certified"), x))
        np.testing.assert_allclose(certified[hit], depth.max(axis=(1, 2, 3))[hit], atol=2e-4)
        checked += hit.sum()
    assert checked > 20


def _corner_list(corners):
    """Corners of shape (n, 4, 2) as ``hull_separation`` takes them: four (x, y) pairs."""
    return [(jnp.asarray(corners[:, i, 0]), jnp.asarray(corners[:, i, 1])) for i in range(4)]


def _shapely_hull_gaps(world, corners):
    """Shapely's signed distance of each hull of four corners (n, 4, 2) from the nearest
    obstacle, and from the nearest circle alone; each of shape (n,)."""
    circles, polygons = shapely_obstacles(world)
    hulls = [shapely.MultiPoint(c).convex_hull for c in corners]
    circle_gap = np.full(len(hulls), np.inf)
    for center, radius in circles:
        circle_gap = np.minimum(circle_gap, shapely.distance(hulls, center) - radius)
    gap = circle_gap
    for polygon in polygons:
        gap = np.minimum(gap, shapely.distance(hulls, polygon))
    return gap, circle_gap


def test_hull_separation_is_a_lower_bound_on_the_shapely_distance_of_the_hull(rng):
    """The separating-axis gap between the convex hull of four points and the nearest obstacle
    never exceeds shapely's distance, over random worlds and hulls near their obstacles, and is
    not uselessly loose: near the distance for the typical hull apart from its obstacles."""
    ratios, exact_circles = [], 0
    for problem in random_world_problems(rng, 40, collision="certified"):
        corners = rng.uniform(-60, 60, (200, 1, 2)) + rng.normal(0, 6, (200, 4, 2))
        ours = np.asarray(hull.hull_separation(problem.arrays.world, _corner_list(corners)))
        oracle, circle_oracle = _shapely_hull_gaps(problem.world, corners)
        assert np.all(ours <= np.maximum(oracle, 0.0) + 1e-3)
        assert np.all(np.isinf(ours) == np.isinf(oracle))  # no obstacles
        apart = np.isfinite(oracle) & (oracle > 1e-3)
        ratios.append(ours[apart] / oracle[apart])
        # circles alone: their gap is the exact distance where apart
        circle_world = problem.arrays.world._replace(
            polygon_valid=np.zeros_like(problem.arrays.world.polygon_valid))
        circle_gap = np.asarray(hull.hull_separation(circle_world, _corner_list(corners)))
        apart = np.isfinite(circle_oracle) & (circle_oracle > 0)
        np.testing.assert_allclose(circle_gap[apart], circle_oracle[apart], atol=2e-4)
        exact_circles += apart.sum()
    ratio = np.concatenate(ratios)
    assert len(ratio) > 2000 and np.median(ratio) > 0.95 and np.mean(ratio > 0.5) > 0.9, (
        len(ratio), np.percentile(ratio, [10, 50]))
    assert exact_circles > 2000


def test_circle_sweep_gaps_are_lower_bounds_on_the_hull_distance_and_exact_at_rest(rng):
    """``world.circle_sweep_gaps``: at rest, every circle's exact separation (``circle_slots``);
    swept, never above shapely's distance of the hull of the four moved end points from the
    circles, and near it, nearer still for a segment sliding along itself."""
    ratios = {False: [], True: []}
    for problem in random_world_problems(rng, 40, collision="certified"):
        world, n = problem.arrays.world, 200
        start = rng.uniform(-60, 60, (n, 2))
        end = start + rng.normal(0, 15, (n, 2))
        link = [jnp.asarray(a, jnp.float32) for a in (*start.T, *end.T)]
        nearest = lambda gaps: np.asarray(functools.reduce(  # noqa: E731
            jnp.minimum, gaps, jnp.full(n, jnp.inf)))
        for sliding in (False, True):
            if sliding:
                along = (end - start) / np.linalg.norm(end - start, axis=1, keepdims=True)
                u, w = along * rng.normal(0, 3, (n, 1)), along * rng.normal(0, 3, (n, 1))
            else:
                u, w = rng.normal(0, 3, (n, 2)), rng.normal(0, 3, (n, 2))
            sweep = world_lib.Sweep(*(jnp.asarray(a, jnp.float32) for a in (*u.T, *w.T)))
            at_rest, swept = world_lib.circle_sweep_gaps(*link, sweep, world)
            np.testing.assert_allclose(nearest(at_rest),
                                       nearest(world_lib.circle_slots(*link, world)),
                                       atol=1e-4, rtol=3e-5)  # float32: ~60 cm
            ours = nearest(swept)
            corners = np.stack([start - u, start + u, end + w, end - w], axis=1)
            _, oracle = _shapely_hull_gaps(problem.world, corners)
            assert np.all(ours <= np.maximum(oracle, 0.0) + 1e-3)
            apart = np.isfinite(oracle) & (oracle > 1e-3)
            ratios[sliding].append(ours[apart] / oracle[apart])
    moving, sliding = (np.concatenate(ratios[key]) for key in (False, True))
    assert len(moving) > 2000 and np.median(moving) > 0.95, np.percentile(moving, [10, 50])
    # sliding: exact where the nearest point is inside the segment, not at an end
    assert len(sliding) > 2000 and np.median(sliding) > 0.99 and np.percentile(sliding, 10) > 0.9


def test_circle_sweep_gaps_of_a_point_a_centre_on_the_segment_and_nan():
    """A segment of length zero is a point: its separation is the point's distance less the
    radius, and the sweep loses its ends' larger move towards the centre; a segment through the
    centre gets no positive gap; NaN coordinates give NaN (never a gap that proves)."""
    world = jaxarm.World(circles=[(10.0, 0.0, 2.0)]).pack((2, 1, 4))  # and an empty circle slot
    cases = {  # (sx, sy, ex, ey, ux, uy, wx, wy)
        "point": (4.0, 0.0, 4.0, 0.0, 1.0, 0.5, -0.5, 3.0),
        "through the centre": (5.0, 0.0, 15.0, 0.0, 0.0, 1.0, 0.0, 1.0),
        "nan": (float("nan"), 0.0, 4.0, 0.0, 1.0, 0.0, 1.0, 0.0)}
    at_rest, swept = {}, {}
    for name, values in cases.items():
        sx, sy, ex, ey, *moves = (jnp.float32(v) for v in values)
        rest, moving = world_lib.circle_sweep_gaps(sx, sy, ex, ey, world_lib.Sweep(*moves), world)
        assert float(rest[1]) == float(moving[1]) == np.inf  # the empty slot
        at_rest[name], swept[name] = float(rest[0]), float(moving[0])
    assert at_rest["point"] == pytest.approx(6.0 - 2.0)
    assert swept["point"] == pytest.approx(6.0 - 2.0 - 1.0)  # towards the centre: +x only
    assert at_rest["through the centre"] <= -2.0 + 1e-5 and swept["through the centre"] <= 0
    assert np.isnan(at_rest["nan"]) and np.isnan(swept["nan"])


@pytest.mark.parametrize("kind", ["circle", "polygon"])
def test_hull_separation_with_the_nearest_obstacle_alone_is_a_lower_bound(rng, kind):
    """Given the circles' (or the polygons') distances from a set every point of the hull is
    within ``spread`` of, only the nearest circle (polygon) gets separating axes: still never
    above shapely's distance of the hull, and where the nearest is the only one of its kind
    within reach, equal to the full test (polygons: at least as tight; elsewhere a polygon's
    distance less the spread can beat its separating-axis gap near a corner)."""
    equal = 0
    for problem in random_world_problems(rng, 40, collision="certified"):
        world = problem.arrays.world
        # a link and its hull: the link's end points moved +/- their velocities
        ends = rng.uniform(-60, 60, (200, 2, 2))
        velocity = rng.normal(0, 1.5, (200, 2, 2))
        corners = np.stack([ends[:, 0] - velocity[:, 0], ends[:, 0] + velocity[:, 0],
                            ends[:, 1] + velocity[:, 1], ends[:, 1] - velocity[:, 1]], axis=1)
        spread = jnp.asarray(np.linalg.norm(velocity, axis=-1).max(axis=1))
        parts = world_lib.separation_parts(*(jnp.asarray(ends[:, e, c]) for e in range(2)
                                             for c in range(2)), world)
        if kind == "circle":
            distances, valid = parts.circles, world.circle_valid
            ours = hull.hull_separation(world, _corner_list(corners),
                                        circle_distances=(distances, spread))
        else:
            distances, valid = list(parts.polygons), world.polygon_valid
            ours = hull.hull_separation(world, _corner_list(corners),
                                        polygon_distances=(parts.polygons, spread))
        ours = np.asarray(ours)
        full = np.asarray(hull.hull_separation(world, _corner_list(corners)))
        oracle, _ = _shapely_hull_gaps(problem.world, corners)
        assert np.all(ours <= np.maximum(oracle, 0.0) + 1e-3)
        apart = np.isfinite(oracle) & (oracle > 0)
        if kind == "circle":
            assert np.all(ours[apart] <= full[apart] + 1e-4)  # the full test is never looser
        if np.sum(np.asarray(valid)) >= 2:
            second = np.sort(np.stack([np.asarray(d) for d in distances]), axis=0)[1]
            alone = apart & (second - np.asarray(spread) > full)
            if kind == "circle":
                np.testing.assert_allclose(ours[alone], full[alone], atol=1e-4)
            else:
                assert np.all(ours[alone] >= full[alone] - 1e-4)
            equal += alone.sum()
    assert equal > 1000, equal
    # NaN never makes a gap: a NaN distance or spread gives NaN, which proves nothing
    nan = jnp.full(2, jnp.nan)
    one = [jnp.zeros(2)] * (len(distances) - 1)
    key = "circle_distances" if kind == "circle" else "polygon_distances"
    for given in (([nan] + one, jnp.ones(2)), ([jnp.ones(2)] * len(distances), nan)):
        given = given if kind == "circle" else (jnp.stack(given[0]), given[1])
        assert np.all(np.isnan(np.asarray(hull.hull_separation(
            world, [(jnp.zeros(2), jnp.zeros(2))] * 4, **{key: given}))))


def swing_shortfalls(lengths, world, about_centre: list, radius) -> list:
    """The certified piece test's first-order bound: each link's swing (``link_swings``) less
    its exact clearance at the centre."""
    speed = [bounds.taylor_derivative_bound([order[j] for order in about_centre], radius)
             for j in range(len(about_centre[0]))]
    clearance = collision.posture_clearance_bound(lengths, world, about_centre[0], exact=True)
    return [swing - bound for swing, bound in
            zip(bounds.link_swings(lengths, speed, radius), clearance)]


def third_order_shortfalls(lengths, world, about_centre: list, radius) -> list:
    """The sweep bound's third-order part alone: each link's ``radius^3 / 6`` times its
    ``LinkMotion.jerk`` less the gap of the hull of its ``bent_corners`` alone (on that
    hull's own axes)."""
    return [radius**3 / 6 * motion.jerk
            - hull.hull_separation(world, bounds.bent_corners(motion, radius))
            for motion in bounds.link_motions(lengths, about_centre, radius)]


@pytest.mark.parametrize("bound_fn", [bounds.sweep_shortfalls, bounds.drift_shortfalls,
                                      swing_shortfalls, third_order_shortfalls],
                         ids=["sweep", "drift", "swing", "third-order"])
@pytest.mark.parametrize("degree", [6, 8])
def test_piece_bounds_hold_on_a_dense_grid(rng, degree, bound_fn):
    """Over a piece ``|r - c| <= radius``, each link's distance to the nearest obstacle (shapely,
    41 times) is at least minus its ``sweep_shortfalls``, its ``drift_shortfalls``, its
    first-order swing bound and the sweep's third-order part alone (margin 0), and each bound
    proves many pieces of moderate radius."""
    problems = random_world_problems(rng, 12, collision="certified")
    with_polygons = [p for p in problems if len(p.world.boxes) + len(p.world.polygons)]
    assert with_polygons and len(with_polygons) < len(problems)
    proved = 0
    with jax.enable_x64(True):
        worlds = with_polygons[:2] + [p for p in problems if p not in with_polygons][:2]
        for problem in worlds + worlds:  # two pieces in each of four worlds
            start, goal = np.asarray(problem.start), np.asarray(problem.goal)
            x = rng.uniform(-60, 60, (40, 3 * (degree - 5)))
            centre, radius = rng.uniform(0.05, 0.95), rng.choice([0.002, 0.01, 0.04])
            about_centre = [
                [a[:, 0] / math.factorial(m) for a in path.joint_angle_list(
                    start, goal, jnp.asarray(x), path.basis_values(degree, [centre], m), order=m)]
                for m in range(degree + 1)]
            bound = -np.stack(bound_fn(problem.arm.lengths, problem.arrays.world,
                                       about_centre, radius), axis=-1)  # (paths, links)
            dense = np.linspace(centre - radius, centre + radius, 41)
            theta = np.asarray(path.joint_angle_array(start, goal, jnp.asarray(x),
                                                      path.basis_values(degree, dense)))
            absolute = np.cumsum(theta, axis=-1)  # (paths, times, links)
            lengths = np.asarray(problem.arm.lengths)
            joints = np.concatenate([np.zeros(absolute.shape[:-1] + (1, 2)), np.cumsum(
                lengths[:, None] * np.stack([np.cos(absolute), np.sin(absolute)], -1), -2)], -2)
            true, _ = oracle_separation(problem.world, joints[..., :-1, :].reshape(-1, 2),
                                        joints[..., 1:, :].reshape(-1, 2))
            true = true.reshape(absolute.shape).min(axis=1)  # (paths, links)
            assert np.all(true >= bound - 1e-6), (true - bound).min()
            proved += np.sum(bound > 0)
    assert proved > 100, proved


def test_the_turning_line_bound_is_a_lower_bound_on_the_swept_patch(rng):
    """``hull.Patch``'s line bound: never above shapely's distance from the segment at 2001 times
    of its linear motion, for circles (less the radius) and boxes, and it proves most
    patches that stay apart from their obstacle."""
    n = 400
    near = rng.normal(0, 20, (n, 2))
    far = near + rng.normal(0, 20, (n, 2))
    near_step, far_step = (rng.normal(0, 1, (n, 2)) * rng.uniform(0, 8, (n, 1))
                           for _ in range(2))
    centre, radius = rng.normal(0, 25, (n, 2)), rng.uniform(0.5, 5, n)
    half = rng.uniform(1, 10, (n, 2))
    corners = [centre + half * np.array(sign) for sign in [(-1, -1), (1, -1), (1, 1), (-1, 1)]]
    with jax.enable_x64(True):  # float64, so the comparison is the bound's, not rounding's
        patch = hull.Patch(*(tuple(jnp.asarray(a[:, c]) for c in range(2))
                             for a in (near, far, near_step, far_step)))
        circle = np.asarray(hull._line_gap(*patch.line_sides(*centre.T),
                                           patch.longest)) - radius
        sides = [patch.line_sides(*c.T) for c in corners]
        box = np.asarray(hull._line_gap(
            functools.reduce(jnp.minimum, [s[0] for s in sides]),
            functools.reduce(jnp.maximum, [s[1] for s in sides]), patch.longest))
    times = np.linspace(-1, 1, 2001)
    checked = {"circle": [0, 0], "box": [0, 0]}
    for i in range(n):
        segments = shapely.linestrings(np.stack(
            [near[i] + times[:, None] * near_step[i], far[i] + times[:, None] * far_step[i]], 1))
        for name, ours, obstacle, less in (
                ("circle", circle[i], shapely.Point(centre[i]), radius[i]),
                ("box", box[i], shapely.Polygon([c[i] for c in corners]), 0.0)):
            oracle = shapely.distance(segments, obstacle).min() - less
            assert ours <= oracle + 1e-9, (name, i, ours, oracle)
            if oracle > 1.0:
                checked[name][0] += 1
                checked[name][1] += ours > 0
    for name, (apart, proved) in checked.items():
        assert apart > 100 and proved > 0.5 * apart, (name, apart, proved)


@pytest.mark.parametrize("obstacle", ["circle", "triangle"])
def test_a_link_turning_beside_an_obstacle_is_proved_where_its_hull_overlaps_it(obstacle):
    """A link of 30 cm turning by +/- 0.1 rad about its middle, 0.5 cm beside a circle (or a
    triangle's corner) there: the hull of its end points' motion covers the obstacle, yet with
    the turning line the gap is nearly the 0.5 cm the link keeps."""
    gap = 0.5
    world = (jaxarm.World(circles=[(15.0, -gap - 2.0, 2.0)]) if obstacle == "circle" else
             jaxarm.World(polygons=[[(15.0, -gap), (13.0, -gap - 4.0), (17.0, -gap - 4.0)]])
             ).pack((1, 1, 4))
    # one joint turning at rate 0.1 rad per unit r about the link's middle: near end (0, 0)
    # moves down as the far end (30, 0) moves up; a piece of radius 1
    corners = [(jnp.float32(0.0), jnp.float32(1.5)), (jnp.float32(0.0), jnp.float32(-1.5)),
               (jnp.float32(30.0), jnp.float32(-1.5)), (jnp.float32(30.0), jnp.float32(1.5))]
    hull_alone = float(hull.hull_separation(world, corners))
    patch = hull.Patch((jnp.float32(0.0), jnp.float32(0.0)),
                       (jnp.float32(30.0), jnp.float32(0.0)),
                       (jnp.float32(0.0), jnp.float32(-1.5)),
                       (jnp.float32(0.0), jnp.float32(1.5)))
    with_line = float(hull.hull_separation(world, corners, patch=patch))
    assert hull_alone < 0 < with_line <= gap + 1e-5
    assert with_line > 0.95 * gap


def chain_among_walls(n_links: int, n_walls: int, rng, margin: float = 0.0) -> jaxarm.Problem:
    """A chain of 10-cm links, self-collision on, turning from along x up to 2 rad,
    beside ``n_walls`` random wall segments below the x axis."""
    start, goal = [0.0] * n_links, [2.0] + [0.1] * (n_links - 1)
    arms = []
    for posture in (start, goal):  # the posture's polyline, links of 10 cm
        angles = np.cumsum(posture)
        joints = np.concatenate([[0.0], np.cumsum(10.0 * np.cos(angles))]), np.concatenate(
            [[0.0], np.cumsum(10.0 * np.sin(angles))])
        arms.append(shapely.LineString(np.stack(joints, axis=1)))
    walls = []
    while len(walls) < n_walls:  # clear of the start and goal by more than the margin
        a = rng.uniform((-60, -60), (60, -2))
        b = a + rng.uniform(-15, 15, 2)
        if min(arm.distance(shapely.LineString([a, b])) for arm in arms) > margin + 1.0:
            walls.append((tuple(a), tuple(b)))
    return jaxarm.Problem(arm=jaxarm.Arm((10.0,) * n_links, self_collision=True), start=start,
                          goal=goal, world=jaxarm.World(segments=walls), margin=margin,
                          init_low=-60.0, init_high=60.0)


def test_a_postures_links_are_cut_into_groups_of_bounded_work():
    world = chain_among_walls(7, 12, np.random.default_rng(0)).arrays.world  # 12 slots x 2
    assert collision.link_edge_pairs(1, world) == 24 and collision.GROUP_WORK == 128
    assert collision.link_groups(7, world) == [range(0, 5), range(5, 7)]
    assert collision.link_groups(5, world) == [range(0, 5)]  # 120 link-edge pairs: one group


def test_a_group_never_run_proves_nothing_free():
    """``by_groups``: the branch taken when the first link's length is not positive (never, for
    a valid arm) gives the carry the value that proves nothing free."""
    groups = [range(0, 1), range(1, 2)]
    run = lambda group, total: total + 1.0  # noqa: E731
    total = jnp.zeros(3)
    ran = collision.by_groups(groups, run, total, [10.0, 5.0], np.inf)
    np.testing.assert_array_equal(ran, 2.0)
    np.testing.assert_array_equal(collision.by_groups(groups, run, total, [0.0, 5.0], np.inf),
                                  np.inf)


@pytest.mark.parametrize("check, margin", [
    ("sampled", 0.0), pytest.param("certified", 0.0, marks=pytest.mark.slow), ("certified", 1.0)])
def test_links_in_groups_give_the_bits_of_links_in_one(rng, monkeypatch, check, margin):
    """A posture's check cut into groups of links, each compiled apart (``GROUP_WORK``), gives
    the fitness and verdicts of the links written out together, and their violation up to
    rounding (a depth adds up the links' depths, which each program rounds in its own way);
    a group never run (an arm whose first link is not positive) leaves nothing free. (The
    sampled check with a margin takes exact distances, one link at a time past
    ``UNROLLED_LINK_EDGES``: no groups.)"""
    from jaxarm.checks.evaluate import evaluate

    problem = chain_among_walls(4, 12, rng, margin).replace(collision=check, n_samples=41)
    x = rng.uniform(-150, 150, (600, problem.n_free)).astype(np.float32)  # about half free
    results = []
    for work in (10**6, 1):  # one group; a group a link
        monkeypatch.setattr(collision, "GROUP_WORK", work)
        jax.clear_caches()
        run = jax.jit(lambda arrays, x: evaluate(problem.spec, arrays, x))
        results.append(run(problem.arrays, x))
    assert len(collision.link_groups(4, problem.arrays.world)) == 4
    one, grouped = results
    np.testing.assert_array_equal(one.fitness, grouped.fitness)
    np.testing.assert_array_equal(np.asarray(one.violation) > 0, np.asarray(grouped.violation) > 0)
    np.testing.assert_allclose(one.violation, grouped.violation, rtol=1e-5, atol=1e-5)
    free = np.mean(np.asarray(results[0].violation) == 0)
    assert 0.05 < free < 0.95
    never = problem.arrays._replace(lengths=np.asarray([0.0] + [10.0] * 3))
    assert not np.any(np.asarray(run(never, x).violation) == 0)


def test_gradients_pass_through_groups_of_links(rng, monkeypatch):
    """``refine``'s barrier differentiates the links' clearance bounds: the same gradients
    with the links in groups as in one."""
    problem = chain_among_walls(4, 3, rng)  # small: a gradient's program grows fast
    world = problem.arrays.world
    theta = [jnp.asarray(rng.uniform(-1, 1, 200), jnp.float32) for _ in range(4)]
    lengths = jnp.asarray(problem.arrays.lengths, jnp.float32)

    def clearance(theta):
        return sum(jnp.sum(jnp.minimum(bound, 3.0)) for bound in collision.link_clearance_bounds(
            lengths, world, link_endpoints(lengths, theta), exact=False))
    gradients = []
    for work in (10**6, 1):
        monkeypatch.setattr(collision, "GROUP_WORK", work)
        gradients.append(jax.jit(jax.grad(clearance))(theta))
    for one, grouped in zip(*gradients):
        np.testing.assert_allclose(one, grouped, rtol=1e-6, atol=1e-6)
    assert sum(float(jnp.abs(g).sum()) for g in gradients[0]) > 0
