"""Independent oracles the tests share: random worlds and shapely checks of segments and paths.

Obstacles are open sets (grazing contact is not a collision), which is shapely's
``relate_pattern(segment, obstacle, "T********")``: the interiors intersect."""

import numpy as np
import shapely

import jaxarm
from jaxarm.oracle import link_segments


# The most random_world makes: 3 circles, 3 boxes and 3 polygons of at most 8 vertices.
CAPACITIES = (3, 6, 8)


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


def random_world_problems(rng, n_worlds, collision):
    """Problems with random worlds around a fixed start and goal (skipping colliding ones),
    under the check ``collision``."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    problems = []
    while len(problems) < n_worlds:
        try:
            problems.append(jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                           world=random_world(rng), capacities=CAPACITIES,
                                           init_low=-60.0, init_high=60.0,
                                           collision=collision))
        except ValueError:
            continue
    return problems


def oracle_path_collides(problem, x, n_samples):
    """Per path: does any link's interior meet any obstacle's at any of n_samples samples.

    The links come from ``jaxarm.oracle.link_segments`` (float64 NumPy, its own kinematics),
    not from the kernels under test.
    """
    segments = link_segments(problem, np.asarray(x), n_samples)  # (paths, samples, links, 2, 2)
    start, end = segments[..., 0, :].reshape(-1, 2), segments[..., 1, :].reshape(-1, 2)
    # Only segments whose bounding box meets some obstacle's can meet its interior: shapely
    # checks those (building every segment as a shapely object was most of the time).
    low, high = np.minimum(start, end), np.maximum(start, end)
    near = np.zeros(len(start), dtype=bool)
    for box in obstacle_bounds(problem.world):
        near |= np.all(high >= box[:2], axis=-1) & np.all(low <= box[2:], axis=-1)
    hit = np.zeros(len(start), dtype=bool)
    hit[near] = oracle_separation(problem.world, start[near], end[near])[1]
    return hit.reshape(len(x), -1).any(axis=-1)


def obstacle_bounds(world: jaxarm.World) -> np.ndarray:
    """(min x, min y, max x, max y) of every obstacle, from shapely; shape (n_obstacles, 4)."""
    circles, polygons = shapely_obstacles(world)
    bounds = [(c.x - r, c.y - r, c.x + r, c.y + r) for c, r in circles]
    return np.array(bounds + [shapely.bounds(p) for p in polygons]).reshape(-1, 4)


def thin_wall_problem(rng):
    """A 0.2 cm wall somewhere in the arm's way: what a sampled check can step over. The
    problem has the world's own capacities: one circle slot and one polygon slot."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    while True:
        corner = rng.uniform(-50, 50, 2)
        size = (0.2, rng.uniform(5, 30)) if rng.random() < 0.5 else (rng.uniform(5, 30), 0.2)
        world = jaxarm.World(boxes=[(tuple(corner), tuple(corner + size))],
                             circles=[(*rng.uniform(-60, 60, 2), rng.uniform(1, 5))])
        try:
            return jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                  world=world)
        except ValueError:
            continue
