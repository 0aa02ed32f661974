"""An independent dense check of motions, with shapely: for tests and benchmarks.

It shares nothing with the kernels but the problem's data and the polynomial basis
(``path.basis_coefficients``, checked against the paper's eq. 10 in the tests): the joint
angles are evaluated in float64 NumPy at ``n_points`` equally spaced times, forward kinematics
is written out again, and every link is measured against every obstacle with shapely's exact
distances.
Needs shapely (``pip install shapely``; it is in the ``test`` extra).
"""

from __future__ import annotations

import numpy as np


def link_segments(problem, x, n_points: int) -> np.ndarray:
    """Every link's end points along the motion, in float64.

    Args:
      x: free parameters, shape (n_paths, n_free).

    Returns:
      Array of shape (n_paths, n_points, n_joints, 2, 2): (start, end) of each link.
    """
    from jaxarm.path import basis_coefficients

    start, goal = np.asarray(problem.start), np.asarray(problem.goal)
    basis = basis_coefficients(problem.degree)  # (degree - 4, degree + 1), float64
    free = np.asarray(x, np.float64).reshape(len(x), problem.degree - 5, len(start))
    polynomial = (np.einsum("pmj,mn->pjn", free, basis[1:])
                  + (goal - start)[:, None] * basis[0])
    polynomial[..., 0] += start
    r = np.linspace(0.0, 1.0, n_points)
    theta = np.einsum("pjn,tn->ptj", polynomial, r[:, None] ** np.arange(problem.degree + 1))
    absolute = np.cumsum(theta, axis=-1)
    steps = np.asarray(problem.arm.lengths) * np.stack([np.cos(absolute), np.sin(absolute)], -1
                                                       ).transpose(3, 0, 1, 2)
    joints = np.concatenate([np.zeros(steps.shape[:-1] + (1,)), np.cumsum(steps, -1)], -1)
    joints = joints.transpose(1, 2, 3, 0)  # (paths, points, joints + 1, 2)
    return np.stack([joints[:, :, :-1], joints[:, :, 1:]], axis=-2)


def dense_clearance(problem, x, n_points: int = 4001) -> np.ndarray:
    """Smallest distance of any link to any obstacle over ``n_points`` times of each motion.

    Negative values are minus the deepest penetration found: how far the deepest point of a
    link lies inside an obstacle (for polygons measured at 33 points of the overlap).

    Args:
      x: free parameters, shape (n_paths, n_free).

    Returns:
      Array of shape (n_paths,), cm (empty for no paths).
    """
    import shapely

    segments = link_segments(problem, x, n_points)
    lines = shapely.linestrings(segments.reshape(-1, 2, 2))
    nearest = np.full(len(lines), np.inf)
    world = problem.world
    for cx, cy, radius in world.circles:
        nearest = np.minimum(nearest, shapely.distance(lines, shapely.Point(cx, cy)) - radius)
    polygons = [shapely.box(*low, *high) for low, high in world.boxes]
    polygons += [shapely.Polygon(vertices) for vertices in world.polygons]
    for polygon in polygons:
        distance = shapely.distance(lines, polygon)
        inside = np.nonzero(shapely.relate_pattern(lines, polygon, "T********"))[0]
        overlap = shapely.intersection(lines[inside], polygon)
        points = shapely.line_interpolate_point(overlap[:, None], np.linspace(0, 1, 33),
                                                normalized=True)
        depth = shapely.distance(points, polygon.exterior).max(axis=1)
        distance[inside] = -np.maximum(depth, 1e-9)  # interiors meet: never >= 0
        nearest = np.minimum(nearest, distance)
    return nearest.reshape(segments.shape[:3]).min(axis=(1, 2))
