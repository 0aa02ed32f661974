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
    if world.link_walls is None:
        return []
    return [Frame(first, lengths[first:], wall, in_frame(first, per_joint))
            for first, wall in enumerate(world.link_walls)]


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
