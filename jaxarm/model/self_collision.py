"""Self-collision: links that are not neighbours must not meet.

The distance between links i and j (j >= i + 2) does not change when the whole arm up to link
i turns or moves, so it is measured in link i's own frame, where link i is a fixed wall from
(0, 0) to (l_i, 0) and link j is link j - i of the chain of links i, i + 1, ..., whose first
joint angle is 0 and whose other joints are the arm's. Each link i = 0 .. n - 3 is such a
*frame*: a chain (its lengths and joint values) against a world of one segment, its links 2,
3, ... tested as any link is tested against obstacles. So every bound of both checks holds for
the pairs as it holds for obstacles, with the motion of the later link relative to the earlier
one, which is slower than either's own.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints
from jaxarm.model.world import World, WorldArrays


class Frame(NamedTuple):
    """The links after link ``first``, in its frame (module docstring)."""

    first: int  # the link that is the wall
    lengths: object  # shape (n_joints - first,): links first, first + 1, ...
    wall: WorldArrays  # link ``first`` as a segment from (0, 0) to (l_first, 0)
    joints: list  # per joint of the chain: its values (joint 0: zeros)


def link_walls(lengths) -> tuple[WorldArrays, ...]:
    """Links 0 .. n - 3, each as a world of one segment in its own frame (host NumPy)."""
    return tuple(World(segments=[((0.0, 0.0), (float(length), 0.0))]).pack()
                 for length in list(lengths)[:-2])


def frames(lengths, world: WorldArrays, per_joint: list) -> list[Frame]:
    """Every frame of an arm whose world checks self-collision (``world.link_walls`` set;
    else none). ``per_joint``: a value per joint (angles, speeds, or a list of per-joint lists,
    one per Taylor order), each kept as it is but the frame's own link's, which is 0."""
    return wall_frames(lengths, world.link_walls or (), per_joint)


def wall_frames(lengths, walls, per_joint: list) -> list[Frame]:
    """``frames`` from the walls themselves (``link_walls``)."""
    return [Frame(first, lengths[first:], wall, in_frame(first, per_joint))
            for first, wall in enumerate(walls)]


def pair_separations(lengths, walls, theta: list) -> list:
    """The exact signed separation of every pair of links (``pairs``' order) at postures:
    their distance, or minus how deep they cross; each of theta's shape (...)."""
    return [world_lib.polygon_separation_xy(*link, frame.wall)[0]
            for frame in wall_frames(lengths, walls, theta)
            for link in link_endpoints(frame.lengths, frame.joints)[TESTED]]


def in_frame(first: int, per_joint: list) -> list:
    """``per_joint`` of the chain from link ``first`` on, that link's own value 0; a list of
    such lists (Taylor orders) is taken order by order."""
    if isinstance(per_joint[0], list):
        return [in_frame(first, order) for order in per_joint]
    return [jnp.zeros_like(per_joint[0])] + list(per_joint[first + 1:])


TESTED = slice(2, None)  # a frame's links tested against its wall: not the wall, nor its neighbour


def pairs(n_joints: int) -> list[tuple[int, int]]:
    """The pairs (i, j) of links checked, in the order the frames give them: (0, 2), (0, 3),
    ..., (1, 3), ..."""
    return [(i, j) for i in range(n_joints - 2) for j in range(i + 2, n_joints)]


def posture_pair_separations(lengths, theta) -> np.ndarray:
    """``pair_separations`` of one posture on the host (float64 NumPy, every pair at once):
    what ``Problem`` checks a start or goal posture with, at a cost that does not grow with a
    compiled program's size. Shape (n_pairs,), ``pairs``' order.

    Apart, the distance: the least of the four end points' distances to the other segment.
    Crossing, minus the depth the checks' separating axes give: the smaller of the two
    segments' overlaps across the other's line.
    """
    absolute = np.cumsum(np.asarray(theta, np.float64))
    steps = np.asarray(lengths, np.float64)[:, None] * np.stack([np.cos(absolute),
                                                                 np.sin(absolute)], axis=-1)
    joints = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    i, j = np.array(pairs(len(absolute)), dtype=int).reshape(-1, 2).T
    p0, p1, q0, q1 = joints[i], joints[i + 1], joints[j], joints[j + 1]

    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    def to_segment(point, a, b):
        edge = b - a
        t = np.clip(np.sum((point - a) * edge, axis=1) / np.sum(edge * edge, axis=1), 0, 1)
        return np.linalg.norm(point - a - t[:, None] * edge, axis=1)

    distance = np.minimum.reduce([to_segment(p0, q0, q1), to_segment(p1, q0, q1),
                                  to_segment(q0, p0, p1), to_segment(q1, p0, p1)])
    across_p = np.stack([cross(p1 - p0, q0 - p0), cross(p1 - p0, q1 - p0)])
    across_q = np.stack([cross(q1 - q0, p0 - q0), cross(q1 - q0, p1 - q0)])
    crossing = (across_p[0] * across_p[1] < 0) & (across_q[0] * across_q[1] < 0)
    depth = np.minimum(np.abs(across_p).min(axis=0) / np.linalg.norm(p1 - p0, axis=1),
                       np.abs(across_q).min(axis=0) / np.linalg.norm(q1 - q0, axis=1))
    return np.where(crossing, -depth, distance)
