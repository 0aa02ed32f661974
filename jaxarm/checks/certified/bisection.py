"""Stage 2 of the certified check: bisection of the windows that stage 1 could not prove.

Each piece of a failing window is tested about its own centre with the tighter bounds of
``bounds`` (the exact distance less the first-order swing, or the swept hull to second order,
the better), and ends *free*, a *witness* (a link closer than the margin at its centre),
*undecided* (within ``certify_tol`` of both), or is split in two. Each lane of a loop walks
one path's pieces depth first and takes the next path when done, so a path's pieces, and its
verdict, do not depend on the rest of the batch.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.checks.certified import bounds
from jaxarm.checks.certified.bits import lowest_set_bit
from jaxarm.checks.certified.samples import Motion
from jaxarm.model import path, self_collision

MAX_LEVELS = 22  # halvings of a sample window; offsets stay exact integers in float32


class Work(NamedTuple):
    """What the window stage leaves for the bisection (``bisect``)."""

    failing_words: jax.Array  # shape=(B, n_words), uint32: the failing windows
    first_window: jax.Array  # shape=(B,), int32: the window to bisect first when it fails
    free_only: jax.Array  # shape=(B,), bool: stop at the first undecided piece too
    work_rows: jax.Array  # shape=(B,), int32: the rows to bisect first, then anything
    n_work: jax.Array  # shape=(), int32: how many rows need it


class _Piece(NamedTuple):
    """A piece of a sample window: the window of sample s split ``level`` times, part ``offset``
    (covering ``r_s + h * ([offset, offset + 1] / 2**level - 1/2)``)."""

    sample: jax.Array  # shape=(n,), int32
    level: jax.Array  # shape=(n,), int32, 0 .. MAX_LEVELS
    offset: jax.Array  # shape=(n,), int32, in [0, 2**level)


class _PieceTest(NamedTuple):
    """What the test of pieces found, each field of shape (n,)."""

    shortfall: jax.Array  # max over links of the better bound's shortfall: <= 0 proves free
    first_order: jax.Array  # max_k (delta_k - (c_k - margin)): the speed bound's shortfall
    second_order: jax.Array  # max_k (e_k - (h_k - margin)): the sweep bound's shortfall
    nearest: jax.Array  # smallest distance of a link to an obstacle at the centre (cm)
    radius: jax.Array  # the piece's half-width in r


def _test_pieces(motion: Motion, pieces: _Piece, tables, step, margin, busy):
    """Shortfall and nearest clearance of pieces, by the better of two bounds per link: the
    exact distance at the centre less the link's swing (``bounds.link_swings``), and the swept
    hull to second order (``bounds.motion_shortfalls``).

    Args:
      motion: each piece's path, x of shape (n, n_free).
      tables: ``samples.derivative_tables``, shape (n_samples, degree + 1, degree - 4).
      step: the sample spacing h.
      busy: bool scalar (may be traced): False when no piece is to be tested (zeros then).

    Returns:
      ``_PieceTest`` of arrays of shape (n,).
    """
    lengths, world, start, goal, x = motion
    dtype = x.dtype
    degree = tables.shape[1] - 1
    n_joints = start.shape[0]
    scale = jnp.asarray(step / 2.0 ** (np.arange(MAX_LEVELS + 1) + 1), dtype)  # exact halvings
    radius = scale[pieces.level]
    # Widened by a few float32 ulps: the centre and radius are rounded once each.
    widened_radius = radius * (1.0 + 2.0**-20)

    def geometry():
        offset = (2 * pieces.offset + 1 - jnp.left_shift(1, pieces.level)).astype(dtype)
        shift = offset * radius  # centre minus the sample, exact up to one rounding
        rows = tables.astype(dtype)[pieces.sample]  # (n, degree + 1, degree - 4)
        # Taylor coefficients of every joint about the sample, then about the centre.
        about_sample = [path.joint_angle_list(start, goal, x, rows[:, order], order,
                                              per_path=True)
                        for order in range(degree + 1)]
        about_centre = []  # about_centre[m][j] = theta_j^(m)(centre) / m!
        for m in range(degree + 1):
            # float: an int binomial past int32 (degree 34 and up) fails to convert in JAX
            terms = [[float(math.comb(i, m)) * about_sample[i][j] for j in range(n_joints)]
                     for i in range(m, degree + 1)]
            value = terms[-1]
            for term in reversed(terms[:-1]):  # Horner in the shift
                value = [t + shift * v for t, v in zip(term, value)]
            about_centre.append(value)
        speed = [bounds.taylor_derivative_bound([order[j] for order in about_centre],
                                                widened_radius)
                 for j in range(n_joints)]
        swings = bounds.link_swings(lengths, speed, widened_radius)
        motions = bounds.link_motions(lengths, about_centre, widened_radius)
        if world.link_walls is None:
            return swings, motions, pair_rows
        # the pairs, after: the frames' rows (``self_collision.over_pairs``, speed first)
        (pair_swing, pair_motion), _ = self_collision.over_pairs(
            lengths, world.link_walls, [speed] + about_centre,
            lambda lengths, wall, joints: list(zip(
                bounds.link_swings(lengths, joints[0], widened_radius),
                bounds.link_motions(lengths, joints[1:], widened_radius))))
        return swings, motions, (pair_swing, pair_motion)

    def stacked(swing, motions, pairs):  # the links on a leading axis: (n_rows, n) each
        swing, motion = jnp.stack(swing), jax.tree.map(lambda *links: jnp.stack(links),
                                                       *motions)
        if pairs is None:
            return swing, motion
        return jax.tree.map(lambda *rows: jnp.concatenate(rows), (swing, motion), pairs)

    # Three branches, taken unless no piece is to be tested (``busy`` False: zeros): the
    # pieces' geometry link by link, the links stacked on an array axis, and the bounds on
    # that axis (written once, not once per link: it compiles faster). XLA's CPU backend
    # fuses a cheap elementwise producer into each of its consumers, so in one
    # computation each bound's fusion computed the Taylor shift and the sines and cosines
    # again, and reading rows of an array inside the fusion that computes it was slow; a
    # branch's results are computed once and kept whole (``benchmarks/RESULTS.md``,
    # *Decisions and negative results*, "The piece test in two branches" and "Geometry
    # stacked over the links").
    n_pair_rows = 0 if world.link_walls is None else len(self_collision.real_rows(n_joints))
    zero = jnp.zeros(x.shape[:1], dtype)
    links = jnp.zeros((n_joints + n_pair_rows,) + x.shape[:1], dtype)
    pair_rows = None if world.link_walls is None else (links[n_joints:],
                                                       bounds.LinkMotion.zeros(links[n_joints:]))
    swing, motions, pairs = jax.lax.cond(
        busy, geometry,
        lambda: ([zero] * n_joints, [bounds.LinkMotion.zeros(zero)] * n_joints, pair_rows))
    swing, motion = jax.lax.cond(busy, stacked,
                                 lambda *_: (links, bounds.LinkMotion.zeros(links)),
                                 swing, motions, pairs)
    first, second, clearance = jax.lax.cond(
        busy, lambda *rows: bounds.tight_bounds(world, *rows, widened_radius, margin, n_joints),
        lambda *_: (links,) * 3, swing, motion)
    return _PieceTest(shortfall=jnp.minimum(first, second).max(axis=0),
                      first_order=first.max(axis=0), second_order=second.max(axis=0),
                      nearest=clearance.min(axis=0), radius=radius)


class Verdict(NamedTuple):
    """What the bisection found for one path. The flags and the count share one integer: XLA's
    CPU backend compiles a kernel for each array the loop writes, in each of its branches."""

    flags: jax.Array  # int32: bit 0 witness, bit 1 undecided, bit 2 exhausted; pieces tested << 3
    nearest: jax.Array  # smallest distance to an obstacle at a tested centre (cm)
    proved: jax.Array  # smallest -shortfall of a free piece (cm; + margin bounds the clearance)
    violation: jax.Array  # (shortfall + tol) * width summed over the pieces that ended open
    witness_r: jax.Array  # the witness piece's centre (r), NaN without one

    @property
    def witness(self) -> jax.Array:  # bool: a piece centre closer than the margin
        return self.flags & 1 != 0

    @property
    def undecided(self) -> jax.Array:  # bool: a piece ended within the tolerance
        return self.flags & 2 != 0

    @property
    def exhausted(self) -> jax.Array:  # bool: the budget or the depth ran out
        return self.flags & 4 != 0

    @property
    def tested(self) -> jax.Array:  # int32: pieces tested
        return self.flags >> 3


class _Lanes(NamedTuple):
    """The paths being bisected, one per lane, each walking its windows depth first."""

    row: jax.Array  # shape=(n_lanes,), int32: the path's row in the batch
    active: jax.Array  # shape=(n_lanes,), bool: a path is being bisected
    x: jax.Array  # shape=(n_lanes, n_free)
    windows: jax.Array  # shape=(n_lanes, n_words), uint32: failing windows not yet finished
    piece: _Piece  # the piece to test next
    pending: jax.Array  # shape=(n_lanes,), int32: bit l set = a right sibling waits at level l
    verdict: Verdict  # running, per lane


def _empty_verdict(shape, dtype) -> Verdict:
    return Verdict(flags=jnp.zeros(shape, jnp.int32), nearest=jnp.full(shape, jnp.inf, dtype),
                   proved=jnp.full(shape, jnp.inf, dtype), violation=jnp.zeros(shape, dtype),
                   witness_r=jnp.full(shape, jnp.nan, dtype))


def _refill(lanes: _Lanes, next_item, work: Work, x):
    """Give idle lanes the next paths of the work list (``x``: all paths, shape (B, n_free)):
    the lanes, and the next item of the list."""
    failing_words, first_window, _, work_rows, n_work = work
    n_rows, dtype = x.shape[0], x.dtype
    idle = ~lanes.active
    item = next_item + jnp.cumsum(idle) - 1
    take = idle & (item < n_work)
    row = jnp.where(take, work_rows[jnp.minimum(item, n_rows - 1)], lanes.row)
    windows = jnp.where(take[:, None], failing_words[row], lanes.windows)
    # The window nearest an obstacle first: a witness, if any, is most likely there.
    closest = first_window[row]
    word = jnp.take_along_axis(windows, (closest >> 5)[:, None], axis=1)[:, 0]
    closest_failing = (word >> (closest & 31).astype(jnp.uint32)) & 1 == 1
    first = jnp.where(closest_failing, closest, lowest_set_bit(windows))
    piece = _Piece(sample=jnp.where(take, first, lanes.piece.sample),
                   level=jnp.where(take, 0, lanes.piece.level),
                   offset=jnp.where(take, 0, lanes.piece.offset))
    fresh = _empty_verdict(take.shape, dtype)
    verdict = jax.tree.map(lambda new, old: jnp.where(take, new, old), fresh, lanes.verdict)
    lanes = _Lanes(row=row, active=lanes.active | take,
                   x=jnp.where(take[:, None], x[row], lanes.x), windows=windows, piece=piece,
                   pending=jnp.where(take, 0, lanes.pending), verdict=verdict)
    return lanes, jnp.minimum(next_item + idle.sum(dtype=jnp.int32), n_work)


class _Outcome(NamedTuple):
    """How each lane's piece ended, each field of shape (n_lanes,), bool."""

    witness: jax.Array  # a link closer than the margin at the centre: the path collides
    undecided: jax.Array  # within the tolerance of both free and a witness
    exhausted: jax.Array  # needs a split past the budget or ``MAX_LEVELS``
    split: jax.Array  # to be split


def _piece_verdict(lanes: _Lanes, test: _PieceTest, n_samples: int, step, tol, margin,
                   proof_margin, budget: int) -> tuple[_Outcome, Verdict]:
    """How each lane's piece ends (module docstring), and the lanes' verdicts with it."""
    piece, verdict = lanes.piece, lanes.verdict
    shortfall, nearest, radius = test.shortfall, test.nearest, test.radius
    # Pieces wholly outside [0, 1] (before r = 0 or after r = 1) need no test.
    half = jnp.left_shift(1, piece.level) >> 1  # 2**(level - 1); 0 at level 0
    outside = (piece.level > 0) & (
        ((piece.sample == 0) & (piece.offset < half))
        | ((piece.sample == n_samples - 1) & (piece.offset >= half)))
    tested = lanes.active & ~outside
    free = shortfall <= 0
    witness = tested & ~(nearest >= margin)  # NaN counts as a witness
    undecided = (tested & ~free & ~witness & (nearest - proof_margin < tol)
                 & (shortfall < tol))
    split = tested & ~free & ~witness & ~undecided
    count = verdict.tested + tested
    exhausted = split & ((piece.level >= MAX_LEVELS) | (count >= budget))
    split &= ~exhausted
    found = (witness.astype(jnp.int32) | undecided.astype(jnp.int32) << 1
             | exhausted.astype(jnp.int32) << 2)
    centre = (piece.sample.astype(radius.dtype) * step  # r at the centre (``_Piece``)
              + (2 * piece.offset + 1 - jnp.left_shift(1, piece.level)).astype(radius.dtype)
              * radius)
    verdict = Verdict(
        flags=(verdict.flags | found) + (tested.astype(jnp.int32) << 3),
        nearest=jnp.minimum(verdict.nearest, jnp.where(tested, nearest, jnp.inf)),
        proved=jnp.minimum(verdict.proved, jnp.where(tested & free, -shortfall, jnp.inf)),
        violation=verdict.violation + jnp.where(witness | undecided,
                                                (shortfall + tol) * (2 * radius), 0.0),
        witness_r=jnp.where(witness, centre, verdict.witness_r))
    return _Outcome(witness=witness, undecided=undecided, exhausted=exhausted,
                    split=split), verdict


def _descend(piece: _Piece, pending, test: _PieceTest, tol, proof_margin):
    """A split: the piece's first descendant at the level where one of the bounds should fit
    inside the clearance (the speed bound shrinks about linearly with the radius, the sweep
    bound about quadratically), with the right siblings on the way down left pending:
    ``(piece, pending)``."""
    clear = jnp.maximum(test.nearest - proof_margin, tol)
    jump = jnp.minimum(
        jnp.ceil(jnp.log2(1.0 + jnp.maximum(test.first_order, 0.0) / clear)),
        jnp.ceil(0.5 * jnp.log2(1.0 + jnp.maximum(test.second_order, 0.0) / clear)))
    jump = jnp.clip(jnp.nan_to_num(jump, nan=1.0), 1, MAX_LEVELS - piece.level
                    ).astype(jnp.int32)
    descend = _Piece(sample=piece.sample, level=piece.level + jump,
                     offset=jnp.left_shift(piece.offset, jump))
    return descend, pending | jnp.left_shift(jnp.left_shift(1, jump) - 1, piece.level + 1)


def _climb(piece: _Piece, pending):
    """No split, siblings pending: the deepest pending right sibling, ``(piece, pending)``."""
    deepest = 31 - jax.lax.clz(pending)
    climb = _Piece(sample=piece.sample, level=deepest,
                   offset=jnp.right_shift(piece.offset, piece.level - deepest) | 1)
    return climb, pending & ~jnp.left_shift(1, deepest)


def _next_window(lanes: _Lanes):
    """No split, no sibling pending (the window is done): the path's failing windows without
    this one, and the lowest of them (``lowest_set_bit``), or the windows as they are where the
    window is not done: ``(window_done, remaining, next_window)``."""
    piece = lanes.piece
    window_done = lanes.pending == 0
    done_bit = jnp.left_shift(jnp.uint32(1), (piece.sample & 31).astype(jnp.uint32))
    word_index = jnp.arange(lanes.windows.shape[1])[None]
    remaining = jnp.where(window_done[:, None] & (piece.sample[:, None] >> 5 == word_index),
                          lanes.windows & ~done_bit[:, None], lanes.windows)
    return window_done, remaining, lowest_set_bit(remaining)


def _test_and_advance(state, motion: Motion, work: Work, tables, step, tol, margin,
                      proof_margin, budget: int):
    """One step of the bisection loop: every lane tests its piece, moves to its next one
    (a descendant, a pending sibling, or the next failing window), and a lane whose path is
    done writes its verdict and takes the next path."""
    lanes, next_item, out = state
    n_rows, n_samples = motion.x.shape[0], tables.shape[0]
    piece = lanes.piece
    test = _test_pieces(motion._replace(x=lanes.x), piece, tables, step, proof_margin,
                        lanes.active.any())
    ended, verdict = _piece_verdict(lanes, test, n_samples, step, tol, margin, proof_margin,
                                    budget)
    split = ended.split
    descend, descend_pending = _descend(piece, lanes.pending, test, tol, proof_margin)
    climb, climb_pending = _climb(piece, lanes.pending)
    window_done, remaining, next_window = _next_window(lanes)
    path_done = lanes.active & (ended.witness | ended.exhausted
                                | (ended.undecided & work.free_only[lanes.row])
                                | (~split & window_done & (next_window >= n_samples)))
    choose = lambda a, b, c: jnp.where(split, a, jnp.where(window_done, c, b))  # noqa: E731
    piece = jax.tree.map(choose, descend, climb,
                         _Piece(sample=next_window, level=jnp.zeros_like(piece.level),
                                offset=jnp.zeros_like(piece.offset)))
    pending = jnp.where(split, descend_pending, jnp.where(window_done, 0, climb_pending))
    windows = jnp.where(split[:, None], lanes.windows, remaining)
    # Finished paths' verdicts written and idle lanes refilled at every step. Doing it only
    # once an eighth of the lanes waited (a branch) compiled every lane array's kernels a
    # second time (benchmarks/RESULTS.md, Decisions and negative results, "The bisection loop
    # writes each lane array once per step").
    target = jnp.where(path_done, lanes.row, n_rows)
    out = jax.tree.map(lambda o, v: o.at[target].set(v, mode="drop"), out, verdict)
    lanes = _Lanes(row=lanes.row, active=lanes.active & ~path_done, x=lanes.x,
                   windows=windows, piece=piece, pending=pending, verdict=verdict)
    lanes, next_item = _refill(lanes, next_item, work, motion.x)
    return lanes, next_item, out


def bisect(motion: Motion, work: Work, tables, step, tol, margin, proof_margin, budget: int,
           n_lanes: int) -> Verdict:
    """Stage 2: bisect the failing windows of the paths ``work.work_rows[:work.n_work]``.

    Each lane walks one path's pieces depth first (sample windows in order; a piece that must
    split is replaced by its first descendant at the level where the bound should hold, with
    the right siblings on the way down left pending), so a path's pieces and their order do
    not depend on the rest of the batch. A lane whose path is finished (every window covered,
    a witness, or out of budget) takes the next path of the work list.

    Args:
      motion: all paths, x of shape (B, n_free).
      work: the failing windows and the rows to bisect.
      tables: ``samples.derivative_tables`` in x's dtype.
      step: the sample spacing h.
      tol: ``certify_tol`` (cm).
      margin: a piece centre closer than this is a witness.
      proof_margin: what a free piece keeps (``check``'s margin plus spare).
      budget: pieces a path tests before none of its pieces is split.
      n_lanes: paths in flight (static).

    Returns:
      ``Verdict`` of arrays of shape (B,) (meaningful on the work rows).
    """
    x = motion.x
    n_rows, dtype = x.shape[0], x.dtype
    zeros = jnp.zeros(n_lanes, jnp.int32)
    lanes = _Lanes(row=zeros, active=jnp.zeros(n_lanes, bool),
                   x=jnp.zeros((n_lanes, x.shape[1]), dtype),
                   windows=jnp.zeros((n_lanes, work.failing_words.shape[1]), jnp.uint32),
                   piece=_Piece(zeros, zeros, zeros), pending=zeros,
                   verdict=_empty_verdict(n_lanes, dtype))
    # The lanes start idle: the first step tests nothing and refills them (a refill of its
    # own here compiled another copy of every lane array's kernels).
    busy = lambda state: state[0].active.any() | (state[1] < work.n_work)  # noqa: E731
    advance = functools.partial(_test_and_advance, motion=motion, work=work, tables=tables,
                                step=step, tol=tol, margin=margin, proof_margin=proof_margin,
                                budget=budget)
    _, _, out = jax.lax.while_loop(busy, advance,
                                   (lanes, jnp.int32(0), _empty_verdict(n_rows, dtype)))
    return out
