"""The broad phase: which obstacles are near a link, so that a check pays for those alone.

A world of more than ``BROAD_PHASE_WORK`` circle slots and polygon edges (``slot_work``)
gets ``NearTables``, built once on the host: a uniform grid over the arm's reach and, per link
and cell, the slots of every obstacle whose bounding box comes within ``link length / 2 +
cell half-diagonal + reach`` of the cell's centre (``reach`` in cm, the tables' guarantee). A
link whose midpoint lies in that cell is then, from every obstacle left out of the list, at
least ``reach`` away: the checks test the listed obstacles exactly (``local_slots``) and
bound the others by ``reach`` (``NearTables.reach``), so every bound stays a lower bound on
the true distance and every verdict stays sound. Smaller worlds keep every slot written out
in one program, the kernels of ``jaxarm.model.world`` as they were, bit for bit.

Obstacles are data here: the listed slots are gathered per link and tested in blocks of
``BLOCK`` slots in a ``lax.scan`` (``over_blocks``), so the compiled program does not grow
with the number of obstacles, and a batch's working set holds one block at a time.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.model.world import CIRCLE_FIELDS, POLYGON_FIELDS, WorldArrays

# Slots tested per step of a scan over obstacles: written out within a block (the kernels'
# fast form), scanned across blocks.
BLOCK = 16
# Worlds of more slot work than this get the broad phase (``NearTables``); smaller ones keep
# every slot written out in one program, which runs faster there (``benchmarks/RESULTS.md``,
# "Scenes at scale": 64 circles or 16 triangles written out, the last sizes before that
# form's cliff).
BROAD_PHASE_WORK = 64
# Cells per axis of the grid over the arm's reach.
GRID_CELLS = 48



class NearTables(NamedTuple):
    """Which obstacle slots lie near a link whose midpoint is in a grid cell (a pytree of
    arrays; ``build`` makes it)."""

    origin: np.ndarray  # shape=(2,), cm: the grid's lower-left corner
    inverse_cell: np.ndarray  # shape=(), 1 / cell size (1 / cm)
    reach: np.ndarray  # shape=(), cm: every slot not listed is at least this far from the link
    circles: np.ndarray  # shape=(n_links, n_cells, n_cells, k_circles), int32 circle slots
    polygons: np.ndarray  # shape=(n_links, n_cells, n_cells, k_polygons), int32 polygon slots


def slot_work(capacities: tuple[int, int, int]) -> int:
    """What a world packed at ``capacities`` costs a link written out: its circle slots plus
    its polygon slots' edges."""
    circles, polygons, vertices = capacities
    return circles + polygons * vertices


def uses_broad_phase(capacities: tuple[int, int, int]) -> bool:
    """Whether a world packed at ``capacities`` gets ``NearTables`` (static)."""
    return slot_work(capacities) > BROAD_PHASE_WORK


def default_reach(lengths, margin: float, certified: bool) -> float:
    """The tables' guarantee (cm): the margin plus a share of the arm's reach, a sixteenth
    for the certified check (a piece of motion whose links move less than the excess over the
    margin is proved with the listed obstacles alone; a longer one is split), a
    thirty-second for the sampled one (whose postures need the margin alone; the excess keeps
    refine's barrier, which looks a few tenths of a cm past the margin, on exact distances).
    A larger reach lists more obstacles per cell."""
    return float(margin) + float(np.sum(lengths)) / (16.0 if certified else 32.0)


def build(world: WorldArrays, lengths, reach: float) -> NearTables:
    """The near tables of a packed world for an arm with link ``lengths`` (cm).

    Args:
      world: the packed world (float64 NumPy arrays).
      lengths: link lengths, shape (n_links,).
      reach: cm, > 0: the distance every slot left out of a list keeps from the link.

    Returns:
      ``NearTables``; each list is padded with the slot index one past the last slot, which
      ``local_slots`` reads as an empty slot, to a multiple of ``BLOCK``.
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    arm_reach = float(np.sum(lengths))
    cell = 2.0 * arm_reach / GRID_CELLS
    origin = np.array([-arm_reach, -arm_reach])
    centres = -arm_reach + cell * (np.arange(GRID_CELLS) + 0.5)  # the same along x and y
    # Widened for float32: a midpoint rounded into a neighbouring cell, a rounded length.
    half_diagonal = cell * np.sqrt(0.5) * (1.0 + 1e-3)
    slack = 1e-4 * arm_reach
    circle_low, circle_high = _circle_boxes(world)
    polygon_low, polygon_high = _polygon_boxes(world)
    circle_lists, polygon_lists = [], []
    for length in lengths:
        radius = 0.5 * length + half_diagonal + reach + slack
        circle_lists.append(_near_lists(centres, circle_low, circle_high, radius))
        polygon_lists.append(_near_lists(centres, polygon_low, polygon_high, radius))
    return NearTables(
        origin=origin, inverse_cell=np.asarray(1.0 / cell), reach=np.asarray(float(reach)),
        circles=_padded(circle_lists, len(circle_low)),
        polygons=_padded(polygon_lists, len(polygon_low)))


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


def _near_lists(centres, low, high, radius) -> list:
    """Per cell (row y, column x), the slots whose box comes within ``radius`` of the cell's
    centre, ascending; a list of n_cells lists of n_cells int arrays."""
    if not len(low):
        return [[np.zeros(0, np.int64)] * len(centres)] * len(centres)
    gap_x = np.maximum(np.maximum(low[None, :, 0] - centres[:, None],
                                  centres[:, None] - high[None, :, 0]), 0.0)  # (n_cells, n)
    gap_y = np.maximum(np.maximum(low[None, :, 1] - centres[:, None],
                                  centres[:, None] - high[None, :, 1]), 0.0)
    rows = []
    for row in range(len(centres)):
        near = gap_y[row][None, :] ** 2 + gap_x ** 2 <= radius * radius  # (n_cells, n)
        rows.append([np.nonzero(cell)[0] for cell in near])
    return rows


def _padded(per_link: list, n_slots: int) -> np.ndarray:
    """Lists as one int32 array (n_links, n_cells, n_cells, k), k a multiple of ``BLOCK``
    (at least one block), padded with ``n_slots`` (an empty slot): a cell's list is one
    contiguous row, gathered whole."""
    longest = max((len(cell) for rows in per_link for row in rows for cell in row), default=0)
    k = BLOCK * max(1, -(-longest // BLOCK))
    n_cells = len(per_link[0])
    table = np.full((len(per_link), n_cells, n_cells, k), n_slots, np.int32)
    for link, rows in enumerate(per_link):
        for y, row in enumerate(rows):
            for x, cell in enumerate(row):
                table[link, y, x, :len(cell)] = cell
    return table


def cell_of(tables: NearTables, mid_x, mid_y):
    """The grid cell (row, column) of points, each of their shape (...), clamped to the grid
    (every link's midpoint lies within the arm's reach, inside the grid)."""
    n_cells = tables.circles.shape[1]
    scale = jnp.asarray(tables.inverse_cell, mid_x.dtype)
    origin = jnp.asarray(tables.origin, mid_x.dtype)

    def index(value, low):
        cell = jnp.floor((value - low) * scale)
        return jnp.clip(jnp.nan_to_num(cell), 0, n_cells - 1).astype(jnp.int32)
    return index(mid_y, origin[1]), index(mid_x, origin[0])


class NearSlots(NamedTuple):
    """The obstacle slots listed near links (``local_slots``), each of the links' shape (...)
    plus a last axis of the list's length."""

    circles: jax.Array  # int32 circle slots (the count of slots: an empty one)
    polygons: jax.Array  # int32 polygon slots


def local_slots(tables: NearTables, link, sx, sy, ex, ey) -> NearSlots:
    """The slots listed near links ``link`` (an int, or an int array broadcasting with the
    coordinates) with end points (sx, sy), (ex, ey), each coordinate of shape (...)."""
    row, column = cell_of(tables, 0.5 * (sx + ex), 0.5 * (sy + ey))
    link = jnp.broadcast_to(jnp.asarray(link, jnp.int32), row.shape)

    def listed(table):  # (n_links, n, n, k) -> (..., k): each list one contiguous row
        return jnp.asarray(table)[link, row, column]
    return NearSlots(circles=listed(tables.circles), polygons=listed(tables.polygons))


def _with_empty_slot(values, fill):
    """Per-slot data with one empty slot appended (the lists' padding points at it)."""
    values = jnp.asarray(values)
    pad = jnp.full((1,) + values.shape[1:], fill, values.dtype)
    return jnp.concatenate([values, pad], axis=0)


def gathered(world: WorldArrays, slots: NearSlots) -> WorldArrays:
    """A world whose slots are the listed ones, per link: each field of shape (k, ..., batch):
    the slot axis first, the links' shape (...) last, so that the kernels of
    ``jaxarm.model.world`` broadcast each slot's numbers against its own link."""
    empty = {"circles": 1e4, "circle_valid": False, "vertices": 1e4, "normals": 0.0,
             "extent_low": 0.0, "extent_high": 0.0, "edge_valid": False,
             "polygon_valid": False}
    batch_ndim = slots.circles.ndim - 1
    fields = {}
    for names, index in ((CIRCLE_FIELDS, slots.circles), (POLYGON_FIELDS, slots.polygons)):
        for name in names:
            values = _with_empty_slot(getattr(world, name), empty[name])[index]
            # (..., k, *slot data) -> (k, *slot data, ...): each slot's data gathered whole
            fields[name] = jnp.moveaxis(values, tuple(range(batch_ndim)),
                                        tuple(range(-batch_ndim, 0)))
    return WorldArrays(**fields)


def over_blocks(world: WorldArrays, slots: NearSlots, value: Callable, combine: Callable,
                identity: float):
    """``combine`` of ``value(block)`` over blocks of ``BLOCK`` listed slots, in a scan whose
    body is the program's one copy of ``value``.

    Args:
      world: the packed world.
      slots: ``local_slots``; circles and polygons are taken in separate blocks (a block holds
        one kind).
      value: block world (``gathered``, BLOCK slots of one kind) -> a pytree of arrays of the
        links' shape (...).
      combine: (pytree, pytree) -> pytree, elementwise, associative (min, max, add).
      identity: ``combine``'s identity (0 for add, inf for min), the value of no blocks.

    Returns:
      The combined pytree.
    """
    no_circles = jnp.zeros(slots.circles.shape[:-1] + (0,), jnp.int32)
    no_polygons = jnp.zeros(slots.polygons.shape[:-1] + (0,), jnp.int32)
    result = None
    for kind, kind_slots in (("circles", slots.circles), ("polygons", slots.polygons)):
        n_blocks = kind_slots.shape[-1] // BLOCK
        if not n_blocks or not getattr(world, "circles" if kind == "circles"
                                       else "vertices").shape[0]:
            continue
        blocks = jnp.moveaxis(kind_slots.reshape(kind_slots.shape[:-1] + (n_blocks, BLOCK)),
                              -2, 0)

        def one_block(block, kind=kind):
            only = (NearSlots(block, no_polygons) if kind == "circles"
                    else NearSlots(no_circles, block))
            return value(gathered(world, only))

        if result is None:
            result = jax.tree.map(lambda shape: jnp.full(shape.shape, identity, shape.dtype),
                                  jax.eval_shape(one_block, blocks[0]))
        result, _ = jax.lax.scan(lambda carry, block: (combine(carry, one_block(block)), None),
                                 result, blocks)
    return result
