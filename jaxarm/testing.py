"""Independent oracles for tests and benchmarks: shapely checks of segments and whole motions.

Needs shapely (``pip install shapely``; it is in the ``test`` extra); nothing in the library
imports this module.

It shares nothing with the kernels but the problem's data and the polynomial basis
(``path.basis_coefficients``, checked against the paper's eq. 10 in the tests): the joint
angles are evaluated in float64 NumPy at ``n_points`` equally spaced times, forward kinematics
is written out again, and every link is measured against every obstacle with shapely's exact
distances.
Obstacles are open sets (grazing contact is not a collision), which is shapely's
``relate_pattern(segment, obstacle, "T********")``: the interiors intersect.
"""

from __future__ import annotations

import numpy as np
import shapely


def link_segments(problem, x, n_points: int) -> np.ndarray:
    """Every link's end points along the motion, in float64.

    Args:
      x: free parameters, shape (n_paths, n_free).

    Returns:
      Array of shape (n_paths, n_points, n_joints, 2, 2): (start, end) of each link.
    """
    return link_segments_at(problem, x, np.broadcast_to(np.linspace(0.0, 1.0, n_points),
                                                        (len(x), n_points)))


def link_segments_at(problem, x, r) -> np.ndarray:
    """Every link's end points at instants of each path, in float64.

    Args:
      x: free parameters, shape (n_paths, n_free).
      r: instants in [0, 1], shape (n_paths, n_r).

    Returns:
      Array of shape (n_paths, n_r, n_joints, 2, 2): (start, end) of each link.
    """
    from jaxarm.model.path import basis_coefficients

    start, goal = np.asarray(problem.start), np.asarray(problem.goal)
    basis = basis_coefficients(problem.degree)  # (degree - 4, degree + 1), float64
    free = np.asarray(x, np.float64).reshape(len(x), problem.degree - 5, len(start))
    polynomial = (np.einsum("pmj,mn->pjn", free, basis[1:])
                  + (goal - start)[:, None] * basis[0])
    polynomial[..., 0] += start
    r = np.asarray(r, np.float64)
    theta = np.einsum("pjn,ptn->ptj", polynomial, r[..., None] ** np.arange(problem.degree + 1))
    absolute = np.cumsum(theta, axis=-1)
    steps = np.asarray(problem.arm.lengths) * np.stack([np.cos(absolute), np.sin(absolute)], -1
                                                       ).transpose(3, 0, 1, 2)
    joints = np.concatenate([np.zeros(steps.shape[:-1] + (1,)), np.cumsum(steps, -1)], -1)
    joints = joints.transpose(1, 2, 3, 0)  # (paths, points, joints + 1, 2)
    return np.stack([joints[:, :, :-1], joints[:, :, 1:]], axis=-2)


def dense_clearance(problem, x, n_points: int = 4001, cutoff: float | None = None) -> np.ndarray:
    """Smallest distance of any link to any obstacle over ``n_points`` times of each motion.

    Negative values are minus the deepest penetration found: how far the deepest point of a
    link lies inside an obstacle (for polygons measured at 33 points of the overlap; a link
    crossing a segment is -1e-9, its depth not measured).

    Args:
      x: free parameters, shape (n_paths, n_free).
      cutoff: cm, optional: measure only the link-obstacle pairs within this distance (found
        by shapely's STRtree), and report ``cutoff`` where none is: the same values below it,
        at a cost that follows the pairs near each link rather than every obstacle.

    Returns:
      Array of shape (n_paths,), cm (empty for no paths).
    """
    segments = link_segments(problem, x, n_points)
    lines = shapely.linestrings(segments.reshape(-1, 2, 2))
    circles, polygons = shapely_obstacles(problem.world)
    if cutoff is None:
        pairs = [(np.arange(len(lines)), index) for index in range(len(circles) + len(polygons))]
        nearest = np.full(len(lines), np.inf)
    else:
        shapes = [center.buffer(radius + 1e-6 * (1.0 + radius), 64) for center, radius in circles]
        line_index, shape_index = shapely.STRtree(shapes + polygons).query(
            lines, predicate="dwithin", distance=cutoff)
        order = np.argsort(shape_index, kind="stable")
        line_index, shape_index = line_index[order], shape_index[order]
        starts = np.searchsorted(shape_index, np.arange(len(shapes) + len(polygons) + 1))
        pairs = [(line_index[starts[i]:starts[i + 1]], i) for i in range(len(starts) - 1)]
        nearest = np.full(len(lines), float(cutoff))
    for rows, index in pairs:
        if index < len(circles):
            center, radius = circles[index]
            nearest[rows] = np.minimum(nearest[rows], shapely.distance(lines[rows], center)
                                       - radius)
            continue
        polygon = polygons[index - len(circles)]
        distance = shapely.distance(lines[rows], polygon)
        inside = np.nonzero(shapely.relate_pattern(lines[rows], polygon, "T********"))[0]
        if isinstance(polygon, shapely.LineString):  # a wall: its crossings, depth unmeasured
            distance[inside] = -1e-9
            nearest[rows] = np.minimum(nearest[rows], distance)
            continue
        overlap = shapely.intersection(lines[rows][inside], polygon)
        points = shapely.line_interpolate_point(overlap[:, None], np.linspace(0, 1, 33),
                                                normalized=True)
        depth = shapely.distance(points, polygon.exterior).max(axis=1)
        distance[inside] = -np.maximum(depth, 1e-9)  # interiors meet: never >= 0
        nearest[rows] = np.minimum(nearest[rows], distance)
    return nearest.reshape(segments.shape[:3]).min(axis=(1, 2))


def self_clearance(problem, x, n_points: int = 4001) -> np.ndarray:
    """Smallest distance between two links that are not neighbours over ``n_points`` times of
    each motion (shapely, float64); -1e-9 where two cross (the depth not measured).

    Args:
      x: free parameters, shape (n_paths, n_free).

    Returns:
      Array of shape (n_paths,), cm; +inf for an arm of fewer than 3 links.
    """
    segments = link_segments(problem, x, n_points)  # (paths, points, links, 2, 2)
    nearest = np.full(len(segments), np.inf)
    n_links = segments.shape[2]
    for i in range(n_links - 2):
        first = shapely.linestrings(segments[:, :, i].reshape(-1, 2, 2))
        for j in range(i + 2, n_links):
            second = shapely.linestrings(segments[:, :, j].reshape(-1, 2, 2))
            distance = np.where(shapely.intersects(first, second), -1e-9,
                                shapely.distance(first, second))
            nearest = np.minimum(nearest, distance.reshape(len(segments), -1).min(axis=1))
    return nearest


def shapely_obstacles(world):
    """Circles as (center, radius) for exact distances; boxes and polygons as Polygons, then
    segments as LineStrings."""
    polygons = [shapely.box(*lo, *hi) for lo, hi in world.boxes]
    polygons += [shapely.Polygon(p) for p in world.polygons]
    polygons += [shapely.LineString(segment) for segment in world.segments]
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


def oracle_path_collides(problem, x, n_samples):
    """Per path: does any link's interior meet any obstacle's at any of n_samples samples.

    The links come from ``link_segments`` (float64 NumPy, its own kinematics),
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


def obstacle_bounds(world) -> np.ndarray:
    """(min x, min y, max x, max y) of every obstacle, from shapely; shape (n_obstacles, 4)."""
    circles, polygons = shapely_obstacles(world)
    bounds = [(c.x - r, c.y - r, c.x + r, c.y + r) for c, r in circles]
    return np.array(bounds + [shapely.bounds(p) for p in polygons]).reshape(-1, 4)
