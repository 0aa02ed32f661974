"""The broad phase: which obstacles are near a link, so that a check pays for those alone.

A world of more than ``BROAD_PHASE_WORK`` circle slots and polygon edges (``slot_work``)
gets ``NearTables``, built once on the host: a uniform grid over the arm's reach, the link's
direction in ``DIRECTION_BINS`` bins, and per link, bin and cell (of the cells the link's
midpoint can reach at some joint angles: the others keep empty lists) the slots of every
obstacle whose bounding box comes within ``width`` of the segment of the link's length through
the cell's centre along the bin's middle direction, where ``width`` = the cell's half-diagonal +
how far a turn within the bin moves the link's points + ``reach`` (cm, the tables'
guarantee). A link whose midpoint lies in that cell and whose direction lies in that bin is
then, from every obstacle left out of the list, at least ``reach`` away: the checks test the
listed obstacles exactly and bound the others by ``reach`` (``NearTables.reach``), so every
bound stays a lower bound on the true distance and every verdict stays sound. Smaller worlds
keep every slot written out in one program, the kernels of ``jaxarm.model.world`` as they
were, bit for bit. Worlds past it with few polygon edges (``reads_every_slot``) get tables
whose one list per link is every slot (``every_slot``), read block by block for all links at
once.

Obstacles are data here: the lists are cut into blocks, each distinct block stored once as
one contiguous row of its slots' numbers (a row gathered whole costs far less than its slots
gathered one by one through an index list), and tested block by block in a ``lax.scan``
(``over_blocks``), so the compiled program does not grow with the number of obstacles, and a
batch's working set holds one block at a time. Lists differ in length, and a link pays for
its own: a block no link's list reaches is skipped, and a block of polygons that few lists
reach is read by those links alone.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.padding import padded_size
from jaxarm.model.world import CIRCLE_FIELDS, POLYGON_FIELDS, WorldArrays

# The fields a block of listed slots carries, per kind: a circle's numbers alone (no valid
# flag: a list's padding is a circle far from the arm, never within the tables' reach, so
# the kernels need not mask it, and a row of circles is a quarter fewer numbers to read;
# ``benchmarks/RESULTS.md``, *Decisions and negative results*, "Circle blocks without their
# valid flags"), a polygon's every field (its padding is masked: its edges' numbers are not
# those of a real polygon).
LISTED_FIELDS = {"circle": ("circles",), "polygon": POLYGON_FIELDS}

# Slots tested per step of a scan over obstacles, circles and polygons: written out within
# a block (the kernels' fast form), scanned across blocks. A list is padded to whole blocks;
# a polygon slot has more numbers, and its smaller block pads less: 4 for the sampled check
# and 8 for the certified one, which ran faster at those sizes (``benchmarks/RESULTS.md``,
# *Decisions and negative results*, "A block's numbers read whole, in blocks of 4 polygons
# under the sampled check").
BLOCK = 16
POLYGON_BLOCK = {"sampled": 4, "certified": 8}
# Worlds of more slot work than this get the broad phase (``NearTables``); smaller ones keep
# every slot written out in one program, which runs faster there (``benchmarks/RESULTS.md``,
# "Scenes at scale": 64 circles or 16 triangles written out, the last sizes before that
# form's cliff).
BROAD_PHASE_WORK = 64
# Worlds past ``BROAD_PHASE_WORK`` of at most this many polygon edges (and at most
# ``BROAD_PHASE_WORK`` circles) get tables that list every slot for every link
# (``every_slot``): a block of polygons read once for all links costs each link far less than
# its own list's blocks gathered for it, which pays only where lists are much shorter than
# the world (``benchmarks/RESULTS.md``, *Decisions and negative results*, "A few dozen
# polygons read by every link at once").
EVERY_SLOT_EDGES = 256
# Cells per axis of the grid over the arm's reach.
GRID_CELLS = 48
# Bins of a link's direction (modulo pi: a segment is the same whichever way it points): a
# list need only hold what lies near the links of one direction, a strip rather than a disc.
DIRECTION_BINS = 16
# ``over_blocks``: a block of the kinds ``GATHERED`` names that at most this share of a batch's
# links read is read by those alone, gathered in chunks of ``CHUNK`` links. Finding and
# gathering them costs about as much per link as reading a block of circles, far less than a
# block of polygons, so circles are not gathered (``benchmarks/RESULTS.md``, *Decisions and
# negative results*, "Each link reads its own list").
SPARSE_SHARE = 0.5
GATHERED = ("polygon",)
CHUNK = 2048



class Nearest(NamedTuple):
    """Where the smallest value of ``over_blocks(..., "nearest")`` was found, per link: each
    field of the links' shape."""

    value: jax.Array  # the smallest value (+inf where no block was read)
    kind: jax.Array  # int32: 0 a circle, 1 a polygon (``KINDS``)
    row: jax.Array  # int32: the row of that kind's listed numbers holding it
    position: jax.Array  # int32: its slot's position within the row


KINDS = ("circle", "polygon")


class NearTables(NamedTuple):
    """The obstacles near a link whose midpoint is in a grid cell and whose direction is in
    a bin, as data (a pytree of arrays; ``build`` makes it, or ``every_slot``: one cell and
    one bin, every slot listed, ``inverse_cell`` 0 and an infinite ``reach``).

    ``circles`` and ``polygons`` hold the listed slots' own numbers: each of the fields
    ``LISTED_FIELDS`` names for that kind, of shape (n_rows, block, *slot data),
    one row per distinct block of slots; ``circle_rows`` and ``polygon_rows``, of shape
    (n_blocks * M,), M = n_links * n_bins * n_cells**2 lists, say which row holds
    block b of list c (``near_cells``) at b * M + c. A block of a link's list is then one
    contiguous row, read whole (``block_world``), with no index list to follow slot by slot;
    lists that share a block share its row.
    """

    origin: np.ndarray  # shape=(2,), cm: the grid's lower-left corner
    inverse_cell: np.ndarray  # shape=(), 1 / cell size (1 / cm)
    reach: np.ndarray  # shape=(), cm: every slot not listed is at least this far from the link
    # The lists as slot indices, shape (n_links, DIRECTION_BINS, n_cells, n_cells, k), int32,
    # padded with the count of slots (no slot): what ``circles`` and ``polygons`` hold the
    # numbers of (``every_slot``'s: one bin and one cell). The checks read their shapes only.
    circle_lists: np.ndarray
    polygon_lists: np.ndarray
    circle_rows: np.ndarray  # int32: the row of each block of each list (see above)
    # int32, shape (M,): how many blocks of list c hold a listed slot (the rest are padding,
    # which ``over_blocks`` skips).
    circle_blocks: np.ndarray
    # LISTED_FIELDS' listed numbers (see above), in the type JAX computes in (float32 unless
    # x64 is on); () without slots of the kind.
    circles: tuple
    polygon_rows: np.ndarray
    polygon_blocks: np.ndarray
    polygons: tuple


def slot_work(capacities: tuple[int, int, int]) -> int:
    """What a world packed at ``capacities`` costs a link written out: its circle slots plus
    its polygon slots' edges."""
    circles, polygons, vertices = capacities
    return circles + polygons * vertices


def uses_broad_phase(capacities: tuple[int, int, int]) -> bool:
    """Whether a world packed at ``capacities`` gets ``NearTables`` (static)."""
    return slot_work(capacities) > BROAD_PHASE_WORK


def reach_candidates(lengths, margin: float, certified: bool) -> tuple[float, ...]:
    """The tables' guarantee (cm) as candidates ``build`` chooses among: the margin plus a
    share of the arm's reach.

    The certified check: a sixteenth, a thirty-second or a sixty-fourth. A piece of motion
    whose links move less than the excess over the margin is proved with the listed obstacles
    alone, a longer one is split: a larger reach splits less, a shorter one lists fewer
    obstacles per cell where they are dense, so ``build`` takes the largest whose lists are
    no longer, in whole blocks, than the shortest's (``benchmarks/RESULTS.md``, *Decisions
    and negative results*, "The certified tables' reach follows the lists": the certified
    search among 1,000 circles, and on the map, whose lists the shorter reach does not
    shorten). The sampled check: a thirty-second or a sixty-fourth, chosen the same way (its
    postures need the margin alone, and shorter lists are fewer blocks to read: "The sampled
    tables' reach follows the lists"; the excess keeps refine's barrier, which looks a few
    tenths of a cm past the margin, on exact distances).
    """
    arm_reach = float(np.sum(lengths))
    shares = (64.0, 32.0, 16.0) if certified else (64.0, 32.0)
    return tuple(float(margin) + arm_reach / share for share in shares)


def build(world: WorldArrays, lengths, reach, collision: str = "certified") -> NearTables:
    """The near tables of a packed world for an arm with link ``lengths`` (cm).

    Args:
      world: the packed world (float64 NumPy arrays).
      lengths: link lengths, shape (n_links,).
      reach: cm, > 0: the distance every slot left out of a list keeps from the link; or
        several such (``reach_candidates``), of which the tables take the largest whose lists
        are no longer, in whole blocks of each kind, than those of the smallest.
      collision: the check the tables are built for ("sampled" or "certified"): it picks
        the polygon block (``POLYGON_BLOCK``); either check reads either's tables.

    Returns:
      ``NearTables``; each list is padded with empty slots (far away and masked) to whole
      blocks of its kind (``BLOCK`` circles, ``POLYGON_BLOCK[collision]`` polygons).
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    reaches = sorted(float(value) for value in np.atleast_1d(reach))
    arm_reach = float(np.sum(lengths))
    cell = 2.0 * arm_reach / GRID_CELLS
    centres = -arm_reach + cell * (np.arange(GRID_CELLS) + 0.5)  # the same along x and y
    # Widened for float32: a midpoint rounded into a neighbouring cell, an angle into a
    # neighbouring bin, a rounded length.
    half_diagonal = cell * np.sqrt(0.5) * (1.0 + 1e-3)
    half_bin = 0.5 * np.pi / DIRECTION_BINS + 1e-3
    slack = 1e-4 * arm_reach
    boxes = {"circles": _circle_boxes(world), "polygons": _polygon_boxes(world)}
    blocks = {"circles": BLOCK, "polygons": POLYGON_BLOCK[collision]}
    # Every point of a link whose midpoint is in the cell and whose direction is in the bin
    # lies within this of the segment through the cell's centre along the bin's middle
    # direction (a turn by at most half_bin moves a point at t from the midpoint by
    # 2 |t| sin(half_bin / 2)), plus the reach. Each link lists the cells its midpoint can
    # reach alone (the others keep empty lists).
    spreads = [half_diagonal + length * np.sin(0.5 * half_bin) for length in lengths]
    reachable = [_reachable_cells(centres, cell, lengths[:link + 1], slack)
                 for link in range(len(lengths))]
    pairs = {(kind, link): _near_pairs(centres, low, high, lengths[link],
                                       spreads[link] + reaches[-1] + slack, reachable[link])
             for kind, (low, high) in boxes.items() for link in range(len(lengths))}

    def pairs_at(reach: float) -> dict:
        kept = {(kind, link): _within(found, lengths[link], spreads[link] + reach + slack)
                for (kind, link), found in pairs.items()}
        return {kind: [kept[kind, link] for link in range(len(lengths))] for kind in boxes}

    def list_blocks(kept: dict) -> tuple:
        return tuple(_list_length(kept[kind], blocks[kind]) for kind in boxes)

    candidates = {value: pairs_at(value) for value in reaches}
    shortest = list_blocks(candidates[reaches[0]])
    reach = max(value for value, kept in candidates.items() if list_blocks(kept) == shortest)
    lists = {kind: _padded(kept, len(boxes[kind][0]), blocks[kind])
             for kind, kept in candidates[reach].items()}
    empty = _padding(arm_reach, reach)
    return NearTables(
        origin=np.array([-arm_reach, -arm_reach]), inverse_cell=np.asarray(1.0 / cell),
        reach=np.asarray(reach), circle_lists=lists["circles"],
        polygon_lists=lists["polygons"],
        circle_blocks=_used_blocks(lists["circles"], len(boxes["circles"][0]), blocks["circles"]),
        polygon_blocks=_used_blocks(lists["polygons"], len(boxes["polygons"][0]),
                                    blocks["polygons"]),
        **_listed_numbers(world, "circle", lists["circles"], blocks["circles"], empty),
        **_listed_numbers(world, "polygon", lists["polygons"], blocks["polygons"], empty))


def every_slot(world: WorldArrays, lengths, collision: str = "certified") -> NearTables:
    """Tables whose every list holds every valid slot of the world (one cell, one direction
    bin, an infinite reach: no slot is left out), for an arm with link ``lengths`` (cm):
    ``over_blocks`` reads each of their blocks once for every link at once, its numbers
    broadcast as those of a world written out. Blocks of ``BLOCK`` circles and
    ``POLYGON_BLOCK[collision]`` polygons, in slot order."""
    n_links, empty = len(lengths), _padding(float(np.sum(lengths)))
    lists, fields = {}, {}
    for kind, valid, block in (("circle", world.circle_valid, BLOCK),
                               ("polygon", world.polygon_valid, POLYGON_BLOCK[collision])):
        slots = np.flatnonzero(np.asarray(valid))
        one = np.full(_whole_blocks(len(slots), block), len(valid), np.int32)
        one[:len(slots)] = slots
        lists[kind] = np.tile(one, (n_links, 1, 1, 1, 1))
        fields[f"{kind}_blocks"] = _used_blocks(lists[kind], len(valid), block)
        fields.update(_listed_numbers(world, kind, lists[kind], block, empty))
    return NearTables(origin=np.zeros(2), inverse_cell=np.asarray(0.0),
                      reach=np.asarray(np.inf), circle_lists=lists["circle"],
                      polygon_lists=lists["polygon"], **fields)


def reads_every_slot(capacities: tuple[int, int, int]) -> bool:
    """Whether a world packed at ``capacities`` gets ``every_slot``'s tables rather than
    ``build``'s (static): past ``BROAD_PHASE_WORK``, with at most ``BROAD_PHASE_WORK``
    circle slots and ``EVERY_SLOT_EDGES`` polygon edges."""
    circles, polygons, vertices = capacities
    return (uses_broad_phase(capacities) and circles <= BROAD_PHASE_WORK
            and polygons * vertices <= EVERY_SLOT_EDGES)


def lists_every_slot(tables: NearTables) -> bool:
    """Whether ``tables`` are ``every_slot``'s: each link's one list (static)."""
    return tables.circle_lists.shape[1:4] == (1, 1, 1)


def _circle_boxes(world: WorldArrays):
    """Bounding boxes of the valid circle slots (others empty), shapes (n_slots, 2)."""
    circles = np.asarray(world.circles, dtype=np.float64)
    low = circles[:, :2] - circles[:, 2:3]
    high = circles[:, :2] + circles[:, 2:3]
    return _only_valid(low, high, np.asarray(world.circle_valid))


def _polygon_boxes(world: WorldArrays):
    """Bounding boxes of the valid polygon slots, shapes (n_slots, 2)."""
    vertices = np.asarray(world.vertices, dtype=np.float64)
    return _only_valid(vertices.min(axis=1), vertices.max(axis=1),
                       np.asarray(world.polygon_valid))


def _only_valid(low, high, valid):
    """Empty slots as boxes at infinity (never near)."""
    low = np.where(valid[:, None], low, np.inf)
    high = np.where(valid[:, None], high, np.inf)
    return low, high


class _Pairs(NamedTuple):
    """(list, slot) pairs of one link length, in order of list then slot: a list is
    bin * n_cells**2 + cell (cell = row * n_cells + column), each pair with the largest gap
    of the slot's box from the segment along its four axes (cm) and the box's squared
    distance from the cell's centre (cm^2), so that the lists of a smaller width are these
    pairs filtered (``_within``). Shapes (n_pairs,)."""

    lists: np.ndarray
    slots: np.ndarray
    gaps: np.ndarray
    centre_squared: np.ndarray


def _reachable_cells(centres, cell: float, lengths, slack: float) -> np.ndarray:
    """Which grid cells (bool, shape (n_cells, n_cells), row then column) hold a point within
    ``slack`` of where the midpoint of an arm's link can be: the last of ``lengths`` (the
    arm's links up to it), its base at the origin, at any joint angles. That midpoint's
    distance from the base is a sum of vectors of lengths a (the links before it, then half
    its own) in any directions: it takes every value from max(0, 2 max(a) - sum(a)) to
    sum(a)."""
    arms = np.append(np.asarray(lengths[:-1], np.float64), 0.5 * lengths[-1])
    outer, inner = arms.sum(), max(0.0, 2.0 * arms.max() - arms.sum())
    nearest = np.maximum(np.abs(centres) - 0.5 * cell, 0.0)  # per row or column
    farthest = np.abs(centres) + 0.5 * cell
    near = np.hypot(nearest[:, None], nearest[None, :])
    far = np.hypot(farthest[:, None], farthest[None, :])
    return (near <= outer + slack) & (far >= inner - slack)


def _near_pairs(centres, low, high, length, width, reachable) -> _Pairs:
    """The (list, slot) pairs of the slots whose box comes within ``width`` of the segment
    of ``length`` through the cell's centre along the bin's middle direction, by the largest
    gap of their projections on four axes (x, y and the segment's direction and normal: each
    a lower bound on the distance) and by the box's distance from the centre (within
    length / 2 + width), in the cells ``reachable`` holds alone (bool, (n_cells, n_cells))."""
    n_cells = len(centres)
    # Candidates: within length / 2 + width of the centre, whatever the direction.
    gap_x = np.maximum(np.maximum(low[None, :, 0] - centres[:, None],
                                  centres[:, None] - high[None, :, 0]), 0.0)  # (n_cells, n)
    gap_y = np.maximum(np.maximum(low[None, :, 1] - centres[:, None],
                                  centres[:, None] - high[None, :, 1]), 0.0)
    radius = 0.5 * length + width
    cells, slots, centre_squared = ([np.zeros(0, np.int64)], [np.zeros(0, np.int64)],
                                    [np.zeros(0, gap_x.dtype)])
    for row in np.flatnonzero(reachable.any(axis=1)):
        squared = gap_y[row][None, :] ** 2 + gap_x ** 2
        column, slot = np.nonzero((squared <= radius * radius) & reachable[row][:, None])
        cells.append(row * n_cells + column)
        slots.append(slot)
        centre_squared.append(squared[column, slot])
    cells, slots, centre_squared = map(np.concatenate, (cells, slots, centre_squared))
    # Each pair's box relative to its cell's centre, and the box's gaps along x and y.
    x, y = centres[cells % n_cells], centres[cells // n_cells]
    box = (low[slots, 0] - x, low[slots, 1] - y, high[slots, 0] - x, high[slots, 1] - y)
    along_x = np.maximum(box[0], -box[2])
    along_y = np.maximum(box[1], -box[3])
    # One bin at a time, mostly in place: arrays of one bin's candidates stay in cache.
    gaps, scratch = np.empty_like(along_x), np.empty((2, len(along_x)))
    found = []
    for direction in (np.arange(DIRECTION_BINS) + 0.5) * (np.pi / DIRECTION_BINS):
        cos, sin = np.cos(direction), np.sin(direction)
        np.subtract(along_x, 0.5 * length * abs(cos), out=gaps)
        np.maximum(gaps, along_y - 0.5 * length * abs(sin), out=gaps)
        gap = _projection_gap(box, cos, sin, scratch)
        np.maximum(gaps, np.subtract(gap, 0.5 * length, out=gap), out=gaps)
        np.maximum(gaps, _projection_gap(box, -sin, cos, scratch), out=gaps)
        pair = np.flatnonzero(gaps <= width)
        found.append((np.full(len(pair), len(found), np.int64), pair, gaps[pair]))
    in_bin, pair, gaps = map(np.concatenate, zip(*found))
    return _Pairs(lists=in_bin * n_cells * n_cells + cells[pair], slots=slots[pair], gaps=gaps,
                  centre_squared=centre_squared[pair])


def _within(pairs: _Pairs, length: float, width: float) -> tuple[np.ndarray, np.ndarray]:
    """One link's ``_near_pairs`` (found within a larger width) within ``width``:
    (lists, slots), in the same order."""
    radius = 0.5 * length + width
    near = (pairs.gaps <= width) & (pairs.centre_squared <= radius * radius)
    return pairs.lists[near], pairs.slots[near]


def _projection_gap(box, axis_x, axis_y, scratch):
    """How far boxes (``box``: x_low, y_low, x_high, y_high relative to a point, each of
    shape (n,)) lie from that point along the unit axis (axis_x, axis_y): the gap between
    their projections on it (<= 0 where a box's projection covers the point's), in
    ``scratch[0]`` (``scratch``: shape (2, n), overwritten)."""
    x_low, y_low, x_high, y_high = box
    x_low, x_high = (x_low, x_high) if axis_x >= 0 else (x_high, x_low)
    y_low, y_high = (y_low, y_high) if axis_y >= 0 else (y_high, y_low)
    first, last = scratch
    np.add(np.multiply(x_low, axis_x, out=first), y_low * axis_y, out=first)
    np.add(np.multiply(x_high, axis_x, out=last), y_high * axis_y, out=last)
    return np.maximum(first, np.negative(last, out=last), out=first)


def _list_length(per_link: list, block: int) -> int:
    """The slots of the longest list (per link, the (lists, slots) of ``_within``), rounded up
    to whole blocks (at least one)."""
    longest = max((int(np.bincount(lists).max(initial=0)) for lists, _ in per_link), default=0)
    return _whole_blocks(longest, block)


def _whole_blocks(n_slots: int, block: int) -> int:
    """``n_slots`` rounded up to whole blocks (at least one)."""
    return block * max(1, -(-n_slots // block))


def _padded(per_link: list, n_slots: int, block: int) -> np.ndarray:
    """Lists (per link, the (lists, slots) of ``_within``) as one int32 array
    (n_links, DIRECTION_BINS, n_cells, n_cells, k), k = ``_list_length``, each list's slots
    ascending, padded with ``n_slots`` (an empty slot)."""
    n_lists = DIRECTION_BINS * GRID_CELLS * GRID_CELLS
    k = _list_length(per_link, block)
    table = np.full((len(per_link), n_lists, k), n_slots, np.int32)
    for link, (lists, slots) in enumerate(per_link):
        key = lists.astype(np.int64) * (n_slots + 1) + slots
        if np.any(key[1:] < key[:-1]):  # a guard: ``_near_pairs`` gives them in this order
            order = np.argsort(key, kind="stable")
            lists, slots = lists[order], slots[order]
        starts = np.flatnonzero(np.diff(lists, prepend=-1))  # where each list's pairs start
        first = np.repeat(starts, np.diff(starts, append=len(lists)))
        table[link, lists, np.arange(len(lists)) - first] = slots
    return table.reshape(len(per_link), DIRECTION_BINS, GRID_CELLS, GRID_CELLS, k)


def _used_blocks(lists: np.ndarray, n_slots: int, block: int) -> np.ndarray:
    """How many blocks of each list hold a listed slot: int32, shape (M,). A list's slots
    come first, so those are the blocks whose first slot is listed."""
    return (lists[..., ::block] < n_slots).sum(axis=-1, dtype=np.int32).reshape(-1)


# The numbers of a masked empty slot, far from any arm (a polygon list's padding; a circle
# list's is a far circle, ``build`` and ``every_slot``), and of an absent field
# (``block_world``).
_MASKED = {"circles": 1e4, "circle_valid": False, "vertices": 1e4, "normals": 0.0,
           "extent_low": 0.0, "extent_high": 0.0, "edge_valid": False, "polygon_valid": False}


def _padding(arm_reach: float, reach: float = 0.0) -> dict:
    """The numbers of a list's padding slot (``_listed_numbers``' ``empty``): a masked polygon,
    and a circle of radius 0 farther from every point within the arm's reach than 1e4 cm plus
    the tables' ``reach`` and the arm's length, so that no bound the checks take from it comes
    near the reach."""
    far = 1e4 + 2.0 * (arm_reach + reach)
    return dict(_MASKED, circles=np.array([far, far, 0.0]))


def _listed_numbers(world: WorldArrays, kind: str, lists: np.ndarray, block: int,
                    empty: dict) -> dict:
    """``NearTables``' rows of one kind ("circle" or "polygon"): ``{kind}_rows`` and the
    numbers of the distinct blocks (``{kind}s``, the fields ``LISTED_FIELDS`` names; () for
    a world without slots of this kind), the lists' padding given its numbers by ``empty``
    (per field: one slot's numbers, broadcast)."""
    names = LISTED_FIELDS[kind]
    n_blocks = lists.shape[-1] // block
    blocks = np.swapaxes(lists.reshape(-1, n_blocks, block), 0, 1)  # (n_blocks, M, block), a view
    n_slots = getattr(world, names[0]).shape[0]
    if not n_slots:
        return {f"{kind}_rows": np.zeros(blocks.shape[0] * blocks.shape[1], np.int32),
                f"{kind}s": ()}
    first, rows = _distinct_blocks(blocks, n_slots)
    distinct = blocks[first // blocks.shape[1], first % blocks.shape[1]]
    # Rows of padding alone, unread, up to ``padded_size`` (a power of two, or a multiple of
    # 4,096): worlds of a few sizes share one program, and XLA's CPU code for the gathers ran
    # slower on some row counts, the map's among them (``benchmarks/RESULTS.md``, *Decisions
    # and negative results*, "Each link's tables list the cells it can reach").
    extra = padded_size(len(distinct)) - len(distinct)
    distinct = np.concatenate([distinct, np.full((extra, block), n_slots, distinct.dtype)])
    numbers = []
    for name in names:
        values = np.asarray(getattr(world, name))
        values = values.astype(jax.dtypes.canonicalize_dtype(values.dtype))  # float64 -> 32
        padding = np.broadcast_to(np.asarray(empty[name], values.dtype), values.shape[1:])
        values = np.concatenate([values, padding[None]])
        numbers.append(values[distinct])  # (n_rows, block, *data)
    return {f"{kind}_rows": rows.reshape(-1).astype(np.int32), f"{kind}s": tuple(numbers)}


def _distinct_blocks(blocks: np.ndarray, n_slots: int) -> tuple[np.ndarray, np.ndarray]:
    """``_distinct_rows`` of the blocks of lists padded with ``n_slots`` (shape (n_blocks, M,
    block): block b of list c; a view will do), taken in order of block then list and
    numbered alike, where most blocks hold padding alone (a list's slots come first, so such
    a block is one whose first slot is padding): those are one row, found without hashing or
    copying them."""
    n_lists = blocks.shape[1]
    empty = (blocks[:, :, 0] == n_slots).reshape(-1)
    full = np.flatnonzero(~empty)
    first, rows = _distinct_rows(blocks[full // n_lists, full % n_lists])
    first = full[first]
    if not empty.any():
        return first, rows
    first_empty = int(np.argmax(empty))
    number = int(np.searchsorted(first, first_empty))  # the empty block's number
    numbered = np.full(len(empty), number, np.int64)
    numbered[full] = rows + (rows >= number)
    return np.insert(first, number, first_empty), numbered


def _distinct_rows(blocks: np.ndarray, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``blocks`` (int32, shape (n, block)), numbered in the order they
    first appear: (the index of each one's first row, shape (n_distinct,); each row's number,
    shape (n,)).

    Each row is reduced to one 64-bit key (a sum of its slots times fixed odd weights,
    wrapping around), which sorts far faster than the rows as strings of bytes; each row is then
    compared with the first row of its key, and where two rows share a key the bytes are
    sorted instead. ``weights``: the keys' weights (tests force collisions with them)."""
    if weights is None:
        weights = np.random.default_rng(0).integers(1, 2**63, blocks.shape[1], np.uint64) | 1
    keys = np.zeros(len(blocks), np.uint64)
    for column, weight in enumerate(weights):
        keys += blocks[:, column].astype(np.uint64) * weight  # wraps around
    _, first, rows = np.unique(keys, return_index=True, return_inverse=True)
    if not np.array_equal(blocks[first][rows], blocks):
        width = blocks.itemsize * blocks.shape[1]
        as_bytes = np.ascontiguousarray(blocks).view(np.dtype((np.void, width)))
        _, first, rows = np.unique(as_bytes.ravel(), return_index=True, return_inverse=True)
    order = np.argsort(first)  # renumbered in order of first appearance
    renumbered = np.empty_like(order)
    renumbered[order] = np.arange(len(order))
    return first[order], renumbered[rows.reshape(-1)]


def cell_of(tables: NearTables, mid_x, mid_y):
    """The grid cell (row, column) of points, each of their shape (...), clamped to the grid
    (every link's midpoint lies within the arm's reach, inside the grid)."""
    n_cells = tables.circle_lists.shape[-2]
    scale = jnp.asarray(tables.inverse_cell, mid_x.dtype)
    origin = jnp.asarray(tables.origin, mid_x.dtype)

    def index(value, low):
        cell = jnp.floor((value - low) * scale)
        return jnp.clip(jnp.nan_to_num(cell), 0, n_cells - 1).astype(jnp.int32)
    return index(mid_y, origin[1]), index(mid_x, origin[0])


def near_cells(tables: NearTables, link, sx, sy, ex, ey):
    """Which list holds the slots near links ``link`` (an int, or an int array broadcasting
    with the coordinates) with end points (sx, sy), (ex, ey), each coordinate of shape (...):
    int32 of that shape, ``NearTables``' c."""
    row, column = cell_of(tables, 0.5 * (sx + ex), 0.5 * (sy + ey))
    n_bins, n_cells = tables.circle_lists.shape[1], tables.circle_lists.shape[-2]
    lists = jnp.asarray(link, jnp.int32) * n_bins + direction_bin(ex - sx, ey - sy, n_bins)
    return (lists * n_cells + row) * n_cells + column


def direction_bin(dx, dy, n_bins: int):
    """The bin of direction (dx, dy) modulo pi, each of shape (...): int32 k in [0, n_bins)
    where the angle lies in [k pi / n_bins, (k + 1) pi / n_bins] (0 for a zero or NaN
    direction).

    The number of the bins' edges the direction, turned into the upper half plane, lies
    counter-clockwise of (the sign of a cross product each): a few multiplications, where
    ``arctan2`` at every sample of every link cost about a quarter of the sampled check among
    1,000 circles (``benchmarks/RESULTS.md``, *Decisions and negative results*, "A link's
    direction bin by cross products"). An angle within rounding of an edge may fall in either
    bin: the tables widen each bin for that (``build``)."""
    flip = dy < 0
    dx, dy = jnp.where(flip, -dx, dx), jnp.where(flip, -dy, dy)
    direction = jnp.zeros(jnp.shape(dx), jnp.int32)
    for edge in np.arange(1, n_bins) * (np.pi / n_bins):
        direction = direction + (np.cos(edge) * dy - np.sin(edge) * dx > 0).astype(jnp.int32)
    return direction


def block_world(numbers: tuple, names: tuple, index) -> WorldArrays:
    """The world of one block of listed slots of one kind: ``numbers`` (``NearTables.circles``
    or ``.polygons``, the fields ``names``) at rows ``index`` (of the links' shape (...)), each
    field of shape (block, *slot data, ...) -- the slot axis first, the links' shape last, so
    that the kernels of ``jaxarm.model.world`` broadcast each slot's numbers against its own
    link -- every circle valid (``LISTED_FIELDS``), and no slots of the other kind.

    The block's numbers pass an optimisation barrier before the kernels use them, so that
    XLA reads them whole rather than fusing the reads into the kernels: measured faster on
    polygon scenes (``benchmarks/RESULTS.md``, *Decisions and negative results*, "A block's
    numbers read whole, in blocks of 4 polygons under the sampled check")."""
    batch_ndim = jnp.ndim(index)
    fields = jax.lax.optimization_barrier(
        {name: jnp.moveaxis(jnp.asarray(values).at[index].get(mode="promise_in_bounds"),
                            tuple(range(batch_ndim)), tuple(range(-batch_ndim, 0)))
         for name, values in zip(names, numbers)})
    if "circles" in fields:
        fields["circle_valid"] = jnp.ones(fields["circles"].shape[:1], bool)
    for name in CIRCLE_FIELDS + POLYGON_FIELDS:
        if name not in fields:
            shape = {"circles": (0, 3), "vertices": (0, 1, 2), "normals": (0, 1, 2),
                     "extent_low": (0, 1), "extent_high": (0, 1), "edge_valid": (0, 1)}
            fields[name] = jnp.zeros(shape.get(name, (0,)),
                                     bool if isinstance(_MASKED[name], bool) else None)
    return WorldArrays(**fields)


def over_blocks(tables: NearTables, cells, value: Callable, combine: str, per_link=()):
    """``combine`` over the blocks of slots listed in ``cells`` (``near_cells``) of
    ``value(block, per_link)``: with the grid's tables, each link paying for its own blocks.

    Block by block (a ``lax.scan``). Tables that list every slot (``every_slot``): each block
    read once, its numbers broadcast against every link. Otherwise a block no link's list
    reaches is skipped; one of a kind ``GATHERED`` names that at most ``SPARSE_SHARE`` of the
    links read is read by those alone, gathered in chunks of ``CHUNK`` links (a ``lax.scan``
    over as many as they can fill, each skipped past them by a ``lax.cond``; in batches of at
    least ``2 * CHUNK`` links); any other is read by every link, its padding included (which
    adds 0 to a sum and, in a minimum, stays above the tables' reach; with every slot listed,
    it can only lower a lower bound). Under a ``jax.vmap`` that batches ``cells`` (several
    problems), the branch is batched too, and every branch runs.

    Args:
      tables: the world's ``NearTables``.
      cells: ``near_cells``, of the links' shape (...).
      value: (block world (``block_world``: a block of slots of one kind), ``per_link`` at
        some links, each of shape (n,)) -> a pytree of arrays of shape (n,); for "nearest",
        the pair (the smallest value over the block's slots, the int32 position of the
        first slot that has it).
      combine: "add" (the sum), "min" or "nearest": the smallest value and where it lies
        (``Nearest``; the first such slot, in the blocks' order).
      per_link: a pytree of arrays broadcasting to the links' shape: each link's own data
        that ``value`` reads.

    Returns:
      The combined pytree (a ``Nearest`` for "nearest"), each array of the links' shape."""
    shape = cells.shape
    n_links = math.prod(shape)
    n_lists = math.prod(tables.circle_lists.shape[:-1])
    cells = cells.reshape(n_links)
    per_link = jax.tree.map(lambda a: jnp.broadcast_to(a, shape).reshape(n_links), per_link)
    elementwise = _COMBINED[combine]
    # A block is gathered where at most SPARSE_SHARE of the links read it: in this many chunks.
    n_chunks = -(-int(SPARSE_SHARE * n_links) // CHUNK)
    result = None
    for kind_code, kind in enumerate(KINDS):
        names, numbers = LISTED_FIELDS[kind], getattr(tables, f"{kind}s")
        rows, blocks = getattr(tables, f"{kind}_rows"), getattr(tables, f"{kind}_blocks")
        if not numbers:
            continue
        gathers = kind in GATHERED and n_links >= 2 * CHUNK

        read_block = functools.partial(_read_block, value, combine, n_lists, kind_code,
                                       names, numbers, rows)
        # Jitted, its trace is cached: ``jax.eval_shape``'s below is the one the scan's step
        # reuses, so ``value`` is traced once, not twice (XLA inlines the call).
        @jax.jit
        def one_block(block, at=None, read_block=read_block):
            """``value`` of block ``block`` at links ``at`` (None: every link; with every
            slot listed, every list's block is list 0's, read once for every link)."""
            if at is None and lists_every_slot(tables):
                return read_block(block, 0, per_link)
            cells_at, own = (cells, per_link) if at is None else jax.tree.map(
                lambda a: a.at[at].get(mode="promise_in_bounds"), (cells, per_link))
            return read_block(block, cells_at, own)

        if result is None:
            result = _identity(combine, jax.eval_shape(one_block, jnp.int32(0)))
        blocks_needed = jnp.asarray(blocks).at[cells].get(mode="promise_in_bounds")

        def every_slot_step(result, block, one_block=one_block):
            return elementwise(result, one_block(block)), None

        def block_step(result, block, one_block=one_block, blocks_needed=blocks_needed,
                       gathers=gathers):
            reads = blocks_needed > block
            count = jnp.sum(reads, dtype=jnp.int32)
            skip = lambda result: result  # noqa: E731

            def every_link(result):
                return elementwise(result, one_block(block))

            def its_readers(result):
                # A scan over the chunks, each skipped past the readers (a ``lax.cond``), not
                # a while loop: reverse-mode differentiable.
                order = _gathered_first(reads, CHUNK)

                def one_chunk(result, first):
                    def read(result):
                        at = jax.lax.dynamic_slice(order, (first,), (CHUNK,))
                        values = one_block(block, jnp.minimum(at, n_links - 1))
                        return _combined_at(result, at, values, combine)
                    return jax.lax.cond(first < count, read, skip, result), None

                firsts = jnp.arange(n_chunks, dtype=jnp.int32) * CHUNK
                return jax.lax.scan(one_chunk, result, firsts)[0]

            if not gathers:
                return jax.lax.switch(jnp.where(count > 0, 1, 0), [skip, every_link],
                                      result), None
            sparse = (count > 0) & (count <= SPARSE_SHARE * n_links)
            branch = jnp.where(sparse, 2, jnp.where(count > 0, 1, 0))
            return jax.lax.switch(branch, [skip, every_link, its_readers], result), None

        n_blocks = rows.shape[0] // n_lists
        step = every_slot_step if lists_every_slot(tables) else block_step
        result, _ = jax.lax.scan(step, result, jnp.arange(n_blocks, dtype=jnp.int32))
    return jax.tree.map(lambda a: a.reshape(shape), result)


def _read_block(value: Callable, combine: str, n_lists: int, kind_code: int, names: tuple,
                numbers: tuple, rows, block, cells, own):
    """``over_blocks``' ``value`` of block ``block`` of lists ``cells`` (an int, or the links')
    at ``own``, read from one kind's ``rows`` and ``numbers`` (``NearTables``; ``names``
    their fields)."""
    row = jnp.asarray(rows).at[block * n_lists + cells].get(mode="promise_in_bounds")
    found = value(block_world(numbers, names, row), own)
    return _found_where(found, kind_code, row) if combine == "nearest" else found


def _gathered_first(flags, chunk: int):
    """The indices of the true ``flags`` (shape (n,)), ascending, then n (no index) up to a
    whole number of chunks: int32, shape (ceil(n / chunk) * chunk,)."""
    n = flags.shape[0]
    padded = -(-n // chunk) * chunk
    slot = jnp.where(flags, jnp.cumsum(flags, dtype=jnp.int32) - 1, padded)
    return jnp.full(padded, n, jnp.int32).at[slot].set(jnp.arange(n, dtype=jnp.int32),
                                                       mode="drop")


def _combined_at(result, at, values, combine: str):
    """``result`` (a pytree of arrays) with ``values`` combined into it (``over_blocks``'
    ``combine``) at indices ``at`` (distinct, but for indices past the end, which are
    dropped)."""
    if combine == "add":
        return jax.tree.map(lambda r, v: r.at[at].add(v, mode="drop"), result, values)
    if combine == "min":
        return jax.tree.map(lambda r, v: r.at[at].min(v, mode="drop"), result, values)
    there = jax.tree.map(lambda r: r.at[at].get(mode="fill", fill_value=0), result)
    return jax.tree.map(lambda r, v: r.at[at].set(v, mode="drop"), result,
                        _nearer(there, values))


def _identity(combine: str, like):
    """What ``over_blocks`` combines its blocks into (``like``: the shapes of a block's
    value): 0 to add to, +inf for a minimum, and for "nearest" +inf found nowhere."""
    if combine == "nearest":
        smallest = jnp.full(like.value.shape, jnp.inf, like.value.dtype)
        return Nearest(smallest, *([jnp.zeros(smallest.shape, jnp.int32)] * 3))
    identity = {"add": 0.0, "min": jnp.inf}[combine]
    return jax.tree.map(lambda a: jnp.full(a.shape, identity, a.dtype), like)


def _found_where(found, kind_code: int, row) -> Nearest:
    """A block's "nearest" ``value`` (the smallest, and its position in the block) with where
    it lies: the kind's code (``KINDS``) and the block's row, per link."""
    smallest, position = found
    like = jnp.zeros(smallest.shape, jnp.int32)
    return Nearest(smallest, like + kind_code, like + row, like + position)


def _nearer(found: Nearest, other: Nearest) -> Nearest:
    """``found``, or ``other`` where its value is smaller or NaN (the first found keeps a tie,
    and a NaN)."""
    closer = (other.value < found.value) | jnp.isnan(other.value)
    return jax.tree.map(lambda a, b: jnp.where(closer, b, a), found, other)


def listed_slot(tables: NearTables, nearest: Nearest, kind: str) -> WorldArrays:
    """The world of one listed slot of ``kind`` per link: the one ``nearest`` names
    (``over_blocks``' "nearest"; where it names the other kind, the first row's first slot),
    each field of shape (1, *slot data, ...), the links' shape last (as ``block_world``)."""
    names, numbers = LISTED_FIELDS[kind], getattr(tables, f"{kind}s")
    block = numbers[0].shape[1]
    slot = jnp.where(nearest.kind == KINDS.index(kind),
                     nearest.row * block + nearest.position, 0)
    one_per_row = tuple(jnp.reshape(a, (-1, 1) + a.shape[2:]) for a in numbers)
    return block_world(one_per_row, names, slot)


# ``over_blocks``' combines, one value into another (pytrees of arrays).
_COMBINED = {"add": functools.partial(jax.tree.map, jnp.add),
             "min": functools.partial(jax.tree.map, jnp.minimum), "nearest": _nearer}
