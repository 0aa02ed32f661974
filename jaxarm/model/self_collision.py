"""Self-collision: links that are not neighbours must not meet.

The distance between links i and j (j >= i + 2) does not change when the whole arm up to link
i turns or moves, so it is measured in link i's own frame, where link i is a fixed wall from
(0, 0) to (l_i, 0) and link j is link j - i of the chain of links i, i + 1, ..., whose first
joint angle is 0 and whose other joints are the arm's. Each link i = 0 .. n - 3 is such a
*frame*: a chain (its lengths and joint values) against a world of one segment, its links 2,
3, ... tested as any link is tested against obstacles. So every bound of both checks holds for
the pairs as it holds for obstacles, with the motion of the later link relative to the earlier
one, which is slower than either's own. The certified check's bounds take the frames on an
array axis (``over_pairs``): traced once for every pair, not once per pair. At a posture each
pair is measured directly, segment against segment: pair by pair, or past ``UNROLLED_PAIRS``
every pair at once on an array axis (``pair_separations``).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.model.arm import link_endpoints
from jaxarm.model.world import World, WorldArrays

TESTED = slice(2, None)  # a frame's links tested against its wall: not the wall, nor its neighbour
# Past this many pairs (an arm of 11 links and more), ``pair_separations`` computes every pair
# at once, the pairs on an array axis: written out pair by pair, XLA fuses them with the rest
# of a posture's check into one loop, scalar code on its CPU backend at 171 pairs and several
# times slower from 45 pairs on, while arms of up to 10 links ran faster written out beside a wall
# (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Many pairs of links on an
# array axis").
UNROLLED_PAIRS = 36


def link_walls(lengths) -> WorldArrays:
    """Links 0 .. n - 3, each as a world of one segment in its own frame, stacked on a leading
    axis (host NumPy): the frames' walls, in ``over_pairs``' order."""
    walls = [World(segments=[((0.0, 0.0), (float(length), 0.0))]).pack()
             for length in list(lengths)[:-2]]
    return WorldArrays(*(None if field[0] is None else np.stack(field) for field in zip(*walls)))


def over_pairs(lengths, walls: WorldArrays, per_joint: list, per_frame):
    """``per_frame`` run on every frame at once: one row per (frame, link) of the frames' chains.

    The frames are padded to the arm's length and taken on an array axis (``jax.vmap``), so
    ``per_frame`` is traced once, whatever the number of pairs: frame i's chain is links i,
    i + 1, ... (its first joint 0), then links of the arm's last length straight on, whose rows
    are padding.

    Args:
      walls: ``link_walls``, the frames' walls (``WorldArrays.link_walls``).
      per_joint: a value per joint, each of shape (...,) (angles, speeds), or a list of such
        lists (one per Taylor order).
      per_frame: ``(lengths, wall, joints) -> list`` of a pytree per link of a chain of
        n_joints links (``lengths`` shape (n_joints,), ``wall`` a one-segment world,
        ``joints`` as ``per_joint``, joint 0 a zero).

    Returns:
      ``(rows, real)``: the pytree of the ``TESTED`` links' values, each leaf of shape
      (n_frames * (n_joints - 2), ...), frame-major (the real rows in ``pairs``' order), and
      ``real``, host bool of shape (n_frames * (n_joints - 2),): False on padding rows, whose
      values are finite and mean nothing.
    """
    nested = isinstance(per_joint[0], list)
    n_joints = len(per_joint[0] if nested else per_joint)
    frame = np.arange(n_joints - 2)[:, None]
    step = np.arange(n_joints)[None, :]
    inside = frame + step < n_joints  # (n_frames, n_joints): the chain's own links
    joint = np.where((step >= 1) & inside, frame + step, n_joints)  # index n_joints: a zero
    link = np.minimum(frame + step, n_joints - 1)

    def gather(values: list):  # (n_frames, n_joints, ...), stacked (not an XLA gather)
        values = jnp.broadcast_arrays(*values)
        values = values + [jnp.zeros_like(values[0])]
        return jnp.stack([jnp.stack([values[i] for i in row]) for row in joint])

    def one_frame(lengths, wall, joints):
        joints = [list(order) for order in joints] if nested else list(joints)
        values = per_frame(lengths, wall, joints)[TESTED]
        return jax.tree.map(lambda *links: jnp.stack(links), *values)

    rows = jax.vmap(one_frame)(jnp.asarray(lengths)[link], walls,
                               [gather(order) for order in per_joint] if nested
                               else gather(per_joint))
    rows = jax.tree.map(lambda leaf: leaf.reshape((-1,) + leaf.shape[2:]), rows)
    return rows, real_rows(n_joints)


def real_rows(n_joints: int) -> np.ndarray:
    """Which of ``over_pairs``' rows are pairs of links (True) and which padding (False):
    host bool of shape ((n_joints - 2) ** 2,)."""
    frame, link = np.arange(n_joints - 2)[:, None], np.arange(2, n_joints)[None, :]
    return (frame + link < n_joints).reshape(-1)


def only_real(rows, real, padding):
    """``rows`` (``over_pairs``) with ``padding`` in place of the padding rows."""
    return jnp.where(real.reshape((-1,) + (1,) * (rows.ndim - 1)), rows, padding)


def pair_separations(links: list, xp=jnp) -> list:
    """The exact signed separation of every pair of links (``pairs``' order): their distance,
    or minus how deep they cross (``segment_separations``).

    Args:
      links: every link's end points, ``link_endpoints``' tuples ``(x0, y0, x1, y1)`` (the
        arm's own frame: no frames needed for a posture), each coordinate of shape (...,).
      xp: ``jax.numpy``, or ``numpy`` on the host.

    Returns:
      A list of n_pairs arrays of shape (...,): pair by pair, elementwise over the batch, as
      ``link_endpoints`` gives the links (a few operations per pair); past ``UNROLLED_PAIRS``
      pairs (with ``jax.numpy``), the rows of one array of shape (n_pairs, ...), computed
      with the pairs on its leading axis.
    """
    checked = pairs(len(links))
    if xp is np or len(checked) <= UNROLLED_PAIRS:
        return [segment_separations(links[i], links[j], xp) for i, j in checked]
    return list(stacked_pair_separations(links))


def stacked_pair_separations(links: list):
    """``pair_separations`` as one array of shape (n_pairs, ...), computed with the pairs on
    its leading axis: one loop however many pairs, which compiles far faster than the pairs
    written out (for code where compiling outweighs running: a witness, a figure;
    ``benchmarks/RESULTS.md``, *Decisions and negative results*, "The distances along a path
    with the links and link pairs on array axes")."""
    first, other = np.array(pairs(len(links))).T
    coordinates = [jnp.stack(jnp.broadcast_arrays(*coordinate))  # (n_links, ...)
                   for coordinate in zip(*links)]
    # The barrier keeps the pairs' loop apart from what reads the separations.
    return jax.lax.optimization_barrier(segment_separations(
        tuple(c[first] for c in coordinates), tuple(c[other] for c in coordinates)))


def segment_separations(p, q, xp=jnp):
    """Signed separation of segments ``p`` and ``q`` (``(x0, y0, x1, y1)``, each coordinate of
    one shape): apart, the distance, the least of the four end points' distances to the other
    segment; crossing, minus how deep: the smaller of the two segments' overlaps across the
    other's line (what the separating axes of each one's normal give)."""
    def to_segment(px, py, ax, ay, bx, by):
        ex, ey, dx, dy = bx - ax, by - ay, px - ax, py - ay
        t = xp.clip((dx * ex + dy * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        return xp.hypot(dx - t * ex, dy - t * ey)

    def across(a, b):  # b's end points' sides of a's line, times a's length
        (ax, ay, bx, by), (cx, cy, dx, dy) = a, b
        ex, ey = bx - ax, by - ay
        return ex * (cy - ay) - ey * (cx - ax), ex * (dy - ay) - ey * (dx - ax)

    distance = functools.reduce(xp.minimum, [
        to_segment(*p[:2], *q), to_segment(*p[2:], *q), to_segment(*q[:2], *p),
        to_segment(*q[2:], *p)])
    across_p, across_q = across(p, q), across(q, p)
    # Each one's ends on both sides of the other's line, and their boxes overlapping: the sides
    # of collinear segments are rounding noise, their boxes exact.
    boxes = [xp.minimum(xp.maximum(p[k], p[k + 2]), xp.maximum(q[k], q[k + 2]))
             >= xp.maximum(xp.minimum(p[k], p[k + 2]), xp.minimum(q[k], q[k + 2]))
             for k in (0, 1)]
    crossing = ((across_p[0] * across_p[1] < 0) & (across_q[0] * across_q[1] < 0)
                & boxes[0] & boxes[1])
    depth = xp.minimum(
        xp.minimum(xp.abs(across_p[0]), xp.abs(across_p[1])) / xp.hypot(p[2] - p[0], p[3] - p[1]),
        xp.minimum(xp.abs(across_q[0]), xp.abs(across_q[1])) / xp.hypot(q[2] - q[0], q[3] - q[1]))
    return xp.where(crossing, -depth, distance)


def pairs(n_joints: int) -> list[tuple[int, int]]:
    """The pairs (i, j) of links checked, in the order the frames give them: (0, 2), (0, 3),
    ..., (1, 3), ..."""
    return [(i, j) for i in range(n_joints - 2) for j in range(i + 2, n_joints)]


def posture_pair_separations(lengths, theta) -> np.ndarray:
    """``pair_separations`` of one posture on the host (float64 NumPy, pair by pair):
    what ``Problem`` checks a start or goal posture with, at a cost that does not grow with a
    compiled program's size. Shape (n_pairs,), ``pairs``' order."""
    absolute = np.cumsum(np.asarray(theta, np.float64))
    steps = np.asarray(lengths, np.float64)[:, None] * np.stack([np.cos(absolute),
                                                                 np.sin(absolute)], axis=-1)
    joints = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    return np.array(pair_separations([(*joints[k], *joints[k + 1])
                                      for k in range(len(absolute))], np))
