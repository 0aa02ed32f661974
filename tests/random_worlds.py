"""Random worlds and problems the tests share (the shapely oracles are ``jaxarm.testing``)."""

import numpy as np
import shapely

import jaxarm

# The most random_world makes: 3 circles, 3 boxes, 3 polygons of at most 8 vertices and a
# segment (3 + 7 x 8 = 59 slot-edges: below the broad phase's threshold, so one program).
CAPACITIES = (3, 7, 8)


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
    segments = []
    for _ in range(rng.integers(0, 2)):
        start = rng.uniform(-60, 60, 2)
        segments.append((tuple(start), tuple(start + rng.normal(0, 20, 2))))
    return jaxarm.World(circles=circles, boxes=boxes, polygons=polygons, segments=segments)


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


def thin_wall_problem(rng, wall: str = "box"):
    """A 0.2 cm wall (``wall="box"``), or a wall of zero thickness at any angle
    (``"segment"``), somewhere in the arm's way: what a sampled check can step over. The
    problem has the world's own capacities: one circle slot and one polygon slot."""
    arm = jaxarm.Arm((30.0, 30.0, 20.0))
    while True:
        corner = rng.uniform(-50, 50, 2)
        size = (0.2, rng.uniform(5, 30)) if rng.random() < 0.5 else (rng.uniform(5, 30), 0.2)
        circles = [(*rng.uniform(-60, 60, 2), rng.uniform(1, 5))]
        if wall == "box":
            world = jaxarm.World(boxes=[(tuple(corner), tuple(corner + size))], circles=circles)
        else:
            turn = rng.uniform(0, np.pi)
            end = corner + max(size) * np.array([np.cos(turn), np.sin(turn)])
            world = jaxarm.World(segments=[(tuple(corner), tuple(end))], circles=circles)
        try:
            return jaxarm.Problem(arm=arm, start=[-1.0, 1.2, 0.8], goal=[1.2, -0.6, 1.0],
                                  world=world)
        except ValueError:
            continue
