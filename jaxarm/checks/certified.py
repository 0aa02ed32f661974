"""The certified continuous collision check: a proof for every r in [0, 1], or a witness.

Three stages, all batched over paths.

0. **Samples** (a fold along the samples, ``path.run_fold``): the nearest obstacle at every
   sample. A sample where a link penetrates an obstacle is a *witness*: the path collides, and
   nothing more is done for it. A search asks for proofs only of the paths that could change
   it (``check``'s ``prove``, from ``pso.Swarm.bar``); the others stop here too. With
   polygons in the world the clearance at every sample is kept for stage 1.

1. **Windows**, for the paths without a witness only (most random paths have one). Around
   every sample r_s lies the
   window ``|r - r_s| <= h / 2`` (h the sample spacing); the windows cover [0, 1]. A point p of
   link k is ``sum_{i<k} l_i u(phi_i) + t l_k u(phi_k)`` with ``phi_i = theta_1 + ... +
   theta_i``; its velocity is ``sum_{j<=k} theta_j'(r) J (p - q_{j-1})`` (q_{j-1} joint j-1's
   position, J the 90 degree rotation), so ``|dp/dr| <= sum_{j<=k} |theta_j'(r)| R_{jk}`` with
   ``R_{jk} = l_j + ... + l_k``. If M_j bounds ``|theta_j'|`` on a window of radius rho, every
   point of link k stays within ``delta_k = rho sum_j M_j R_{jk}`` of where it is at the centre;
   with c_k a lower bound on link k's distance to the nearest obstacle at the centre, ``c_k -
   margin >= delta_k`` proves it clear over the window (obstacles are open sets). A second
   bound sees the direction of the motion: the link moves as its linear part (its end points
   along their velocities) plus at most ``rho^2 / 2 A_k`` (A_k bounds the acceleration of its
   points), and against a circle only the linear part's speed towards the circle counts (so a
   link sliding along it, the swarm's typical grazing path, loses little; against a polygon,
   the faster end's full speed). Either bound proves a link; a window's *shortfall* is the
   largest excess over the links (``collision.drift_shortfalls``: no separating axes of the
   swept hull). The failing windows are recorded as a bit mask. How the windows are tested
   depends on the world (static):

   - *circles alone* (``_dense_window_pass``): every window of the paths without a witness
     gets the drift test, a fold along the samples over ``WINDOW_CHUNK`` paths at a time;
   - *with polygons* (``_screened_window_pass``): a window is first screened with no
     geometry at all: the smallest clearance of any link at its sample (kept by stage 0)
     against the largest swing of any link (the last link's delta), which proves most of a
     search's windows; only the others get the drift test, compacted across paths
     ``PAIR_CHUNK`` windows at a time. The screen proves a window only where the drift test
     would (c_k is at least the smallest clearance, delta_k at most the last link's), so the
     failing windows are the same up to rounding. Against circles alone the drift test
     costs so little per window that the screen and the compaction cost more than they saved
     (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Windows screened by
     their swing").

2. **Bisection** of the failing windows of every path without a witness. Each piece is tested
   about its own centre with two bounds on every link's distance to the obstacles over the
   piece, and the better of the two counts:

   - *first order*: the exact signed distance at the centre, less the radius times a bound on
     the link's speed (the exact Taylor expansion of the joint speeds on the piece, from the
     path's derivatives of every order at the centre);
   - *second order* (``collision.sweep_shortfalls``): a lower bound on the distance between
     the obstacles and the link's linear motion (its end points moved along their
     velocities), less ``radius^2 / 2`` times a bound on the acceleration of the link's
     points. The bound is the better of two: the separating-axis gap of the convex hull of
     the end points' motion (the hull's exact distance from the circle nearest the link at
     the centre, when apart, and the nearest polygon's edge normals; every other obstacle
     counts its distance less the hull's spread), and how far the link's turning line
     stays from that circle, or from every vertex of that polygon, over the piece. The
     hull fits a link sliding past an obstacle; the line a link turning about a point
     beside one, where the hull covers part of the obstacle. A link sweeping past an
     obstacle at a small clearance c is proved with pieces of radius about ``sqrt(c)``
     instead of c, so a path the swarm drives against an obstacle costs a few pieces
     instead of a number growing as ``1 / sqrt(c)``. In a world of circles alone, a
     third-order bound counts per circle where it is better: the hull of the end points'
     quadratic motion (their curvature at the centre, exact), less ``radius^3 / 6`` times a
     bound on the third derivative.

   A piece ends as

   - *free*: shortfall <= 0 (a search asks for ``-search_spare``: ``check``'s ``spare``);
   - *witness*: some link is closer than the margin at the centre (penetrates, for margin 0);
   - *undecided*: no link is ``certify_tol`` clear at the centre and none can be ``certify_tol``
     deeper than the margin inside the piece (``min_k c_k < tol`` and shortfall ``< tol``);

   and is split in two otherwise. So a motion whose clearance (minus the margin) is at least
   ``tol`` everywhere is never undecided: it is proved free once the pieces are small enough;
   one that penetrates by at least ``tol`` somewhere is never undecided there: its pieces shrink
   until a centre lands inside the obstacle. A path stops at its first witness, and one whose
   freedom alone matters (``check``'s ``free_only``, from a search's ``pso.Bar``) at its first
   undecided piece too. Each lane of a loop walks one path's pieces
   depth first and takes the next path when done, so the work grows with the pieces that need
   it, not with a fixed budget per path. The loop runs until its slowest path is decided, so
   few lanes suit few paths: it has ``FEW_LANES`` lanes when at most ``FEW_PATHS`` paths
   need bisecting (``FEW_PATHS_CPU`` on CPU, where idle lanes cost as much as busy ones),
   ``LANES`` otherwise. Both loops are compiled, except for a batch of at most that many
   paths, which can only need the narrow one; the tests run the other loop with 16 lanes
   (on a GPU, with 128). No piece of a path is split once the path has tested ``budget``
   pieces (pieces that need no split are still tested), and pieces stop at ``MAX_LEVELS``
   halvings; a path that needs a split past either is *exhausted*: neither free nor
   colliding, and counted (``Certificate.exhausted``).

Pieces are located by integers (sample, level, offset) and expanded about their sample with
float64 tables of the basis derivatives, so a piece far below float32's spacing of r still has
an accurate centre. The guarantee holds up to floating-point rounding of the geometry (float32:
a few 1e-5 cm on an arm of 80 cm).

Violation (for constraint handling), zero exactly when the motion is certified free:
- a witness at a sample: how far the nearest link is inside the margin at the deepest sample
  (cm). Not summed over the samples (the sum rewards paths that swing fast through an
  obstacle), nor the positive window shortfalls summed (their speed term favours slow paths);
  both escaped less often under feasibility rules (``benchmarks/RESULTS.md``, *Decisions and
  negative results*, "Constraint rules compare depth x distance"). The rules compare it times
  the travelling distance (``constraints.path_measures``);
- otherwise: ``(shortfall + tol) * width`` summed over the pieces that end as witness or
  undecided (plus ``tol * h`` when the budget ran out); for a path stopped early
  (``free_only``), over the pieces tested by then; inf for a path not to prove (``prove``).
  A path that grazes an obstacle between samples gets a small violation that shrinks as it
  moves clear, so feasibility rules lead the swarm into the certifiable region.

Results per path depend only on that path (its pieces are visited in the same order whatever
else is in the batch, in chunks or lanes of any count), so they are bit-identical for any batch
size.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.checks import collision as collision_lib
from jaxarm.model import path
from jaxarm.model import world as world_lib
from jaxarm.model.problem import ProblemArrays, ProblemSpec

MAX_LEVELS = 22  # halvings of a sample window; offsets stay exact integers in float32
LANES = 1024  # paths bisected at once ...
FEW_LANES = 64  # ... or FEW_LANES at a time when at most ``_few_paths()`` need it:
FEW_PATHS, FEW_PATHS_CPU = 2048, 4096  # on an accelerator, on CPU
WINDOW_CHUNK = 1024  # paths per call of the dense window pass (``_dense_window_pass``)
SWING_CHUNK = 512  # paths per call of the screened pass's swing test (``_screened_window_pass``)
PAIR_CHUNK = 4096  # ... and windows per call of its drift test
# Pieces per path: the count shares an int32 with three flags, and a path can test a few more
# than its budget (the first piece of each failing window left, and the pending siblings).
MAX_BUDGET = 2**27


class CertifiedCheck(NamedTuple):
    """The certified verdict on a batch of paths, each field of shape (...,)."""

    violation: jax.Array  # >= 0, zero iff free (see the module docstring)
    free: jax.Array  # bool: proved collision-free (clearance >= margin) for every r in [0, 1]
    colliding: jax.Array  # bool: a time where a link is closer than the margin was found
    clearance: jax.Array  # cm: see ``Certificate``
    exhausted: jax.Array  # bool: the budget ran out before a verdict
    pieces: jax.Array  # int32: pieces of windows the bisection tested (0: none needed)


class _Motion(NamedTuple):
    """Paths and the problem data they move in: what every stage of the check reads."""

    lengths: jax.Array  # shape=(n_joints,), cm
    world: world_lib.WorldArrays
    start: jax.Array  # shape=(n_joints,), rad
    goal: jax.Array  # shape=(n_joints,), rad
    x: jax.Array  # shape=(B, n_free), the paths' free parameters


class _Work(NamedTuple):
    """What the window stage leaves for the bisection (``_bisect``)."""

    failing_words: jax.Array  # shape=(B, n_words), uint32: the failing windows
    first_window: jax.Array  # shape=(B,), int32: the window to bisect first when it fails
    free_only: jax.Array  # shape=(B,), bool: stop at the first undecided piece too
    work_rows: jax.Array  # shape=(B,), int32: the rows to bisect first, then anything
    n_work: jax.Array  # shape=(), int32: how many rows need it


class _Windows(NamedTuple):
    """What the window stage found on the paths it passed, each field of shape (B, ...)."""

    failing: jax.Array  # shape=(B, n_words), uint32: bit s % 32 of word s // 32 = window s
    worst_passed: jax.Array  # shape=(B,), largest shortfall of a certified window (<= 0)


class _WindowPass(NamedTuple):
    """Carry of the dense window pass along the samples."""

    pending: jax.Array  # shape=(B,), the previous sample's window shortfall, not yet recorded
    worst_passed: jax.Array  # shape=(B,), largest shortfall of a certified window (<= 0)
    failing: jax.Array  # shape=(B, n_words), uint32: bit s % 32 of word s // 32 = window s


def _no_windows(batch: tuple, dtype, n_samples: int) -> _WindowPass:
    """The dense window pass before any sample: nothing failing."""
    return _WindowPass(
        pending=jnp.full(batch, -jnp.inf, dtype),
        worst_passed=jnp.full(batch, -jnp.inf, dtype),
        failing=jnp.zeros(batch + (-(-n_samples // 32),), jnp.uint32),
    )


def _drift_fold(motion: _Motion, degree, n_samples, margin) -> path.SampleFold:
    """Stage 1's drift test of every window, as a fold over the samples; ``finish`` returns
    the last ``_WindowPass``.

    The shortfalls alone: the nearest clearance at the samples comes from stage 0. With both,
    every link's distance had two consumers, and XLA's CPU backend materialised them (the
    pass ran about 4 times slower: ``benchmarks/RESULTS.md``, *Decisions and negative
    results*, "The window pass computes the shortfall alone").
    """
    lengths, world, start, goal, x = motion
    tables, reach = _window_tables(degree, n_samples, x.dtype)

    def record(carry: _WindowPass, index) -> _WindowPass:
        failing = ~(carry.pending <= 0)  # NaN (from non-finite angles) fails too
        bit = jnp.left_shift(failing.astype(jnp.uint32), (index & 31).astype(jnp.uint32))
        return carry._replace(
            worst_passed=jnp.maximum(carry.worst_passed,
                                     jnp.where(failing, -jnp.inf, carry.pending)),
            failing=carry.failing | jnp.where(
                index >> 5 == jnp.arange(carry.failing.shape[-1]), bit[..., None], jnp.uint32(0)),
        )

    def add_sample(carry, sample):
        rows = tables[sample.index]
        about_sample = [path.joint_angle_list(start, goal, x, rows[order], order)
                        for order in range(degree + 1)]
        # Recorded one step late: the fusion computing a sample's values then feeds nothing
        # else in the same step, and XLA does not repeat the geometry per consumer.
        carry = record(carry, sample.index - 1)
        shortfalls = collision_lib.drift_shortfalls(lengths, world, about_sample, reach, margin)
        return carry._replace(pending=functools.reduce(jnp.maximum, shortfalls))

    return path.SampleFold(init=_no_windows(x.shape[:-1], x.dtype, n_samples), step=add_sample,
                           finish=lambda carry: record(carry, jnp.int32(n_samples - 1)),
                           max_order=0)


def _few_paths() -> int:
    """The most paths to bisect that still get the narrow loop (module docstring, stage 2):
    on CPU a wide loop pays for its idle lanes, so it waits for more work
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "The wide bisection loop on
    CPU too")."""
    return FEW_PATHS_CPU if jax.default_backend() == "cpu" else FEW_PATHS


def _nearest_fold(lengths, world, x) -> path.SampleFold:
    """Stage 0 as a fold: the smallest clearance bound of any link at any sample (cm; < 0:
    a penetration, exact) and the first sample where it was found, each of shape (B,).

    One value per sample: the window pass's shortfall and this distance share every link's
    distances, and XLA's CPU backend then materialises each link-obstacle distance on its own
    (several times slower: ``benchmarks/RESULTS.md``, *Fitness-kernel throughput*), so the
    window pass runs apart, and only on the paths this one finds no witness on.
    """
    def add_sample(carry, sample):
        nearest, closest = carry
        here = functools.reduce(jnp.minimum, collision_lib.posture_clearance_bound(
            lengths, world, sample.derivatives[0]))
        nearer = jnp.minimum(nearest, here)  # ``here`` read once, for the same reason
        return nearer, jnp.where(nearer < nearest, sample.index, closest)

    return path.SampleFold(
        init=(jnp.full(x.shape[:-1], jnp.inf, x.dtype), jnp.zeros(x.shape[:-1], jnp.int32)),
        step=add_sample, finish=lambda carry: carry, max_order=0)


def _dense_window_pass(motion: _Motion, open_rows, n_open, degree, n_samples,
                       margin) -> _Windows:
    """Stage 1 in a world of circles alone: the drift test of every window of the paths
    ``open_rows[:n_open]``, ``WINDOW_CHUNK`` paths at a time.

    Each chunk is a scan over the samples, of 1024 paths: chosen when polygon scenes ran this
    pass too, whose scan steps cost far more than their paths on CPU (``benchmarks/RESULTS.md``,
    *Decisions and negative results*, "The window pass computes the shortfall alone"; not
    measured again for circles alone, nor on a GPU).

    Args:
      motion: all paths, x of shape (B, n_free).
      open_rows: shape (B,), int32: the rows to pass first, then anything.
      n_open: int32 scalar.

    Returns:
      ``_Windows``: the pass's values on the open rows, no failing window elsewhere.
    """
    x = motion.x
    n_rows = x.shape[0]
    chunk = min(WINDOW_CHUNK, n_rows)
    padded = jnp.concatenate([open_rows, jnp.zeros(-n_rows % chunk, jnp.int32)])

    def pass_chunk(state):
        first, out = state
        rows = jax.lax.dynamic_slice(padded, (first,), (chunk,))
        xs = x[rows]
        windows = path.run_fold(_drift_fold(motion._replace(x=xs), degree, n_samples, margin),
                                motion.start, motion.goal, xs, degree, n_samples)
        target = jnp.where(first + jnp.arange(chunk) < n_open, rows, n_rows)
        out = jax.tree.map(lambda o, v: o.at[target].set(v, mode="drop"), out, windows)
        return first + chunk, out

    _, out = jax.lax.while_loop(lambda state: state[0] < n_open, pass_chunk,
                                (jnp.int32(0), _no_windows((n_rows,), x.dtype, n_samples)))
    return _Windows(failing=out.failing, worst_passed=out.worst_passed)


def _sample_clearances(lengths, world, start, goal, x, degree, n_samples):
    """Stage 0: the smallest clearance bound of any link at each sample (cm; < 0: a
    penetration, exact), shape (n_samples, B)."""
    return path.sample_values(
        lambda sample: functools.reduce(jnp.minimum, collision_lib.posture_clearance_bound(
            lengths, world, sample.derivatives[0])),
        start, goal, x, degree, n_samples)


def _window_swings(lengths, start, goal, x, tables, reach):
    """How far any point of the arm can move over each sample's window (cm), shape
    (n_samples, B): the last link's swing (``collision.link_swings``), the largest of any
    link's. No geometry: the joints' Taylor coefficients about the sample alone."""
    def value(sample):
        rows = tables[sample.index]
        about_sample = [path.joint_angle_list(start, goal, x, rows[order], order)
                        for order in range(tables.shape[1])]  # order 0 unused: compiled away
        speed = [collision_lib.taylor_derivative_bound([order[j] for order in about_sample],
                                                       reach)
                 for j in range(start.shape[0])]
        return collision_lib.link_swings(lengths, speed, reach)[-1]

    return path.sample_values(value, start, goal, x, tables.shape[1] - 1, tables.shape[0])


def _screened_window_pass(motion: _Motion, nearest, open_, degree, n_samples,
                          margin) -> _Windows:
    """Stage 1 in a world with polygons (module docstring) on the paths where ``open_`` (shape
    (B,), bool), from stage 0's clearances ``nearest`` (shape (n_samples, B)).

    A window is proved first by its sample's clearance against the arm's largest swing
    (``_window_swings``: no geometry), on the open paths only, ``SWING_CHUNK`` at a time; only
    the windows that fail that are tested with the drift bound, compacted across paths,
    ``PAIR_CHUNK`` at a time.
    """
    lengths, world, start, goal, x = motion
    n_rows = x.shape[0]
    tables, reach = _window_tables(degree, n_samples, x.dtype)
    open_rows, n_open, place = _rows_first(open_, with_place=True)
    n_words = -(-n_samples // 32)
    rows_chunk = min(SWING_CHUNK, n_rows)
    padded = jnp.concatenate([open_rows, jnp.zeros(-n_rows % rows_chunk, jnp.int32)])

    def swing_chunk(state):  # open rows first..first + rows_chunk, in ``open_rows`` order
        first, hard_words, worst = state
        rows = jax.lax.dynamic_slice(padded, (first,), (rows_chunk,))
        shortfall = (_window_swings(lengths, start, goal, x[rows], tables, reach)
                     - (nearest[:, rows] - margin))
        hard = ~(shortfall <= 0) & (first + jnp.arange(rows_chunk) < n_open)[None]  # NaN too
        passed = jnp.where(hard, -jnp.inf, shortfall).max(axis=0)
        return (first + rows_chunk,
                jax.lax.dynamic_update_slice(hard_words, _packed(hard.T), (first, 0)),
                jax.lax.dynamic_update_slice(worst, passed, (first,)))

    _, hard_words, worst = jax.lax.while_loop(
        lambda state: state[0] < n_open, swing_chunk,
        (jnp.int32(0), jnp.zeros((padded.shape[0], n_words), jnp.uint32),
         jnp.full(padded.shape, -jnp.inf, x.dtype)))
    hard_words = hard_words.reshape(-1)  # open rows' words, in ``open_rows`` order
    counts = jax.lax.population_count(hard_words).astype(jnp.int32)
    through = jnp.cumsum(counts)  # hard windows in the words up to each one
    n_hard = through[-1]
    chunk = min(PAIR_CHUNK, 32 * hard_words.shape[0])

    def pass_chunk(state):
        first, failing, worst = state
        rank = first + jnp.arange(chunk, dtype=jnp.int32)
        word = jnp.minimum(jnp.searchsorted(through, rank, side="right"), through.shape[0] - 1)
        bit = _nth_set_bit(hard_words[word], rank - (through[word] - counts[word]))
        sample = jnp.minimum((word % n_words) * 32 + bit, n_samples - 1)
        xs, rows = x[padded[word // n_words]], tables[sample]
        about_sample = [path.joint_angle_list(start, goal, xs, rows[:, order], order,
                                              per_path=True)
                        for order in range(degree + 1)]
        drift = functools.reduce(jnp.maximum, collision_lib.drift_shortfalls(
            lengths, world, about_sample, reach, margin))
        valid = rank < n_hard
        fails = ~(drift <= 0)
        failing = failing.at[jnp.where(valid & fails, word, failing.shape[0])].add(
            jnp.left_shift(jnp.uint32(1), bit.astype(jnp.uint32)), mode="drop")
        worst = worst.at[jnp.where(valid & ~fails, word // n_words, worst.shape[0])].max(
            drift, mode="drop")
        return first + chunk, failing, worst

    _, failing, worst = jax.lax.while_loop(
        lambda state: state[0] < n_hard, pass_chunk,
        (jnp.int32(0), jnp.zeros_like(hard_words), worst))
    failing = failing.reshape(-1, n_words)
    return _Windows(failing=jnp.where(open_[:, None], failing[place], jnp.uint32(0)),
                    worst_passed=jnp.where(open_, worst[place], -jnp.inf))


def _packed(bits):
    """Bits (shape (B, n), bool) as words: bit i % 32 of word i // 32, shape (B, ceil(n / 32)),
    uint32."""
    n_words = -(-bits.shape[1] // 32)
    padded = jnp.pad(bits, ((0, 0), (0, 32 * n_words - bits.shape[1])))
    as_words = padded.reshape(bits.shape[0], n_words, 32).astype(jnp.uint32)
    return (as_words << jnp.arange(32, dtype=jnp.uint32)[None, None]).sum(axis=-1, dtype=jnp.uint32)


def _nth_set_bit(words, n):
    """Index of the set bit of rank ``n`` (0: the lowest) of each of ``words`` (uint32, shape
    (m,); ``n`` int32, shape (m,), below each word's count), by halving: shape (m,), int32."""
    index = jnp.zeros_like(n)
    for width in (16, 8, 4, 2, 1):
        below = jax.lax.population_count(words & jnp.uint32((1 << width) - 1)).astype(n.dtype)
        above = n >= below
        n = jnp.where(above, n - below, n)
        words = jnp.where(above, words >> width, words)
        index = index + jnp.where(above, width, 0)
    return index


def _window_tables(degree: int, n_samples: int, dtype):
    """What both window passes expand the paths with: ``_derivative_tables`` in ``dtype``, and
    a window's radius, half the sample spacing widened as ``_test_pieces``'s radius."""
    reach = 1.0 / (n_samples - 1) / 2 * (1.0 + 2.0**-20)
    return (jnp.asarray(_derivative_tables(degree, n_samples), dtype),
            jnp.asarray(reach, dtype))


def _derivative_tables(degree: int, n_samples: int) -> np.ndarray:
    """Every basis function's derivatives of every order at the samples, divided by the
    order's factorial (Taylor coefficients); float64, shape (n_samples, degree + 1, degree - 4)."""
    r = np.linspace(0.0, 1.0, n_samples)
    return np.stack([path.basis_values(degree, r, order) / math.factorial(order)
                     for order in range(degree + 1)], axis=1)


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


def _test_pieces(motion: _Motion, pieces: _Piece, tables, step, margin, busy):
    """Shortfall and nearest clearance of pieces, with tight bounds (module docstring, stage 2).

    Args:
      motion: each piece's path, x of shape (n, n_free).
      tables: ``_derivative_tables``, shape (n_samples, degree + 1, degree - 4).
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
    reach_radius = radius * (1.0 + 2.0**-20)

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
        speed = [collision_lib.taylor_derivative_bound([order[j] for order in about_centre],
                                                       reach_radius)
                 for j in range(n_joints)]
        return (collision_lib.link_swings(lengths, speed, reach_radius),
                collision_lib.link_motions(lengths, about_centre, reach_radius))

    def stacked(swing, motions):  # the links on a leading axis: (n_joints, n) each
        return jnp.stack(swing), jax.tree.map(lambda *links: jnp.stack(links), *motions)

    def bounds(swing, motion):  # every link at once: (n_joints, n) each
        parts = world_lib.separation_parts(*motion.near, *motion.far, world)
        clearance = collision_lib.smallest_separation(parts, swing)
        first = swing - (clearance - margin)
        second, = collision_lib.motion_shortfalls(world, [motion], reach_radius[None], margin,
                                                  [parts])
        return first, second, clearance

    # Three branches, taken unless no piece is to be tested (``busy`` False: zeros): the
    # pieces' geometry link by link, the links stacked on an array axis, and the bounds on
    # that axis (written once: the piece test alone compiles in about half the time of one
    # written per link; per step it is slower on some scenes, faster on others). XLA's CPU
    # backend fuses a cheap elementwise producer into each of its consumers, so in one
    # computation each bound's fusion computed the Taylor shift and the sines and cosines
    # again, and reading rows of an array inside the fusion that computes it was slow; a
    # branch's results are computed once and kept whole (``benchmarks/RESULTS.md``,
    # *Decisions and negative results*, "The piece test in two branches" and "Geometry
    # stacked over the links").
    zero = jnp.zeros(x.shape[:1], dtype)
    links = jnp.zeros((n_joints,) + x.shape[:1], dtype)
    swing, motions = jax.lax.cond(
        busy, geometry,
        lambda: ([zero] * n_joints, [collision_lib.LinkMotion.zeros(zero)] * n_joints))
    swing, motion = jax.lax.cond(busy, stacked,
                                 lambda *_: (links, collision_lib.LinkMotion.zeros(links)),
                                 swing, motions)
    first, second, clearance = jax.lax.cond(busy, bounds, lambda *_: (links,) * 3, swing,
                                            motion)
    return _PieceTest(shortfall=jnp.minimum(first, second).max(axis=0),
                      first_order=first.max(axis=0), second_order=second.max(axis=0),
                      nearest=clearance.min(axis=0), radius=radius)


class _Verdict(NamedTuple):
    """What the bisection found for one path. The flags and the count share one integer: XLA's
    CPU backend compiles a kernel for each array the loop writes, in each of its branches."""

    flags: jax.Array  # int32: bit 0 witness, bit 1 undecided, bit 2 exhausted; pieces tested << 3
    nearest: jax.Array  # smallest distance to an obstacle at a tested centre (cm)
    proved: jax.Array  # smallest -shortfall of a free piece (cm; + margin bounds the clearance)
    violation: jax.Array  # (shortfall + tol) * width summed over the pieces that ended open

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
    verdict: _Verdict  # running, per lane


def _lowest_set_bit(words):
    """Index of the lowest set bit of each row of ``words`` (shape (n, n_words), uint32; bit b
    of word w is index 32 w + b), shape (n,); a large number where none is set."""
    lowest = words & (~words + jnp.uint32(1))
    trailing = jax.lax.population_count(lowest - jnp.uint32(1)).astype(jnp.int32)
    word = jnp.arange(words.shape[-1], dtype=jnp.int32)[None]
    index = jnp.where(words != 0, 32 * word + trailing, 1 << 30)
    return index.min(axis=-1)  # int32 with 64-bit types on too: the loop carries it


def _empty_verdict(shape, dtype) -> _Verdict:
    return _Verdict(flags=jnp.zeros(shape, jnp.int32), nearest=jnp.full(shape, jnp.inf, dtype),
                    proved=jnp.full(shape, jnp.inf, dtype), violation=jnp.zeros(shape, dtype))


def _bisect(motion: _Motion, work: _Work, tables, step, tol, margin, proof_margin,
            budget: int, n_lanes: int) -> _Verdict:
    """Stage 2: bisect the failing windows of the paths ``work_rows[:n_work]``.

    Each lane walks one path's pieces depth first (sample windows in order; a piece that must
    split is replaced by its first descendant at the level where the bound should hold, with
    the right siblings on the way down left pending), so a path's pieces and their order do
    not depend on the rest of the batch. A lane whose path is finished (every window covered,
    a witness, or out of budget) takes the next path of the work list.

    Args:
      motion: all paths, x of shape (B, n_free).
      work: the failing windows and the rows to bisect.
      margin: a piece centre closer than this is a witness.
      proof_margin: what a free piece keeps (``check``'s margin plus spare).
      budget: pieces a path tests before none of its pieces is split.
      n_lanes: paths in flight.

    Returns:
      ``_Verdict`` of arrays of shape (B,) (meaningful on the work rows).
    """
    lengths, world, start, goal, x = motion
    failing_words, first_window, free_only, work_rows, n_work = work
    n_rows, dtype = x.shape[0], x.dtype
    n_samples = tables.shape[0]

    def refill(lanes: _Lanes, next_item):
        """Give idle lanes the next paths of the work list."""
        idle = ~lanes.active
        item = next_item + jnp.cumsum(idle) - 1
        take = idle & (item < n_work)
        row = jnp.where(take, work_rows[jnp.minimum(item, n_rows - 1)], lanes.row)
        windows = jnp.where(take[:, None], failing_words[row], lanes.windows)
        # The window nearest an obstacle first: a witness, if any, is most likely there.
        closest = first_window[row]
        word = jnp.take_along_axis(windows, (closest >> 5)[:, None], axis=1)[:, 0]
        closest_failing = (word >> (closest & 31).astype(jnp.uint32)) & 1 == 1
        first = jnp.where(closest_failing, closest, _lowest_set_bit(windows))
        piece = _Piece(sample=jnp.where(take, first, lanes.piece.sample),
                       level=jnp.where(take, 0, lanes.piece.level),
                       offset=jnp.where(take, 0, lanes.piece.offset))
        fresh = _empty_verdict(take.shape, dtype)
        verdict = jax.tree.map(lambda new, old: jnp.where(take, new, old), fresh, lanes.verdict)
        lanes = _Lanes(row=row, active=lanes.active | take,
                       x=jnp.where(take[:, None], x[row], lanes.x), windows=windows, piece=piece,
                       pending=jnp.where(take, 0, lanes.pending), verdict=verdict)
        return lanes, jnp.minimum(next_item + idle.sum(dtype=jnp.int32), n_work)

    def test_and_advance(state):
        lanes, next_item, out = state
        piece, verdict = lanes.piece, lanes.verdict
        test = _test_pieces(_Motion(lengths, world, start, goal, lanes.x), piece, tables,
                            step, proof_margin, lanes.active.any())
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
        verdict = _Verdict(
            flags=(verdict.flags | found) + (tested.astype(jnp.int32) << 3),
            nearest=jnp.minimum(verdict.nearest, jnp.where(tested, nearest, jnp.inf)),
            proved=jnp.minimum(verdict.proved, jnp.where(tested & free, -shortfall, jnp.inf)),
            violation=verdict.violation + jnp.where(witness | undecided,
                                                    (shortfall + tol) * (2 * radius), 0.0))
        # Descend: to the level where one of the bounds should fit inside the clearance
        # (the speed bound shrinks about linearly with the radius, the sweep bound about
        # quadratically), leaving right siblings pending.
        clear = jnp.maximum(nearest - proof_margin, tol)
        jump = jnp.minimum(
            jnp.ceil(jnp.log2(1.0 + jnp.maximum(test.first_order, 0.0) / clear)),
            jnp.ceil(0.5 * jnp.log2(1.0 + jnp.maximum(test.second_order, 0.0) / clear)))
        jump = jnp.clip(jnp.nan_to_num(jump, nan=1.0), 1, MAX_LEVELS - piece.level
                        ).astype(jnp.int32)
        descend = _Piece(sample=piece.sample, level=piece.level + jump,
                         offset=jnp.left_shift(piece.offset, jump))
        descend_pending = lanes.pending | jnp.left_shift(jnp.left_shift(1, jump) - 1,
                                                         piece.level + 1)
        # Or climb: to the deepest pending right sibling.
        deepest = 31 - jax.lax.clz(lanes.pending)
        climb = _Piece(sample=piece.sample, level=deepest,
                       offset=jnp.right_shift(piece.offset, piece.level - deepest) | 1)
        climb_pending = lanes.pending & ~jnp.left_shift(1, deepest)
        # Or move on: to the next failing window of the path.
        window_done = lanes.pending == 0
        done_bit = jnp.left_shift(jnp.uint32(1), (piece.sample & 31).astype(jnp.uint32))
        word_index = jnp.arange(lanes.windows.shape[1])[None]
        remaining = jnp.where(window_done[:, None] & (piece.sample[:, None] >> 5 == word_index),
                              lanes.windows & ~done_bit[:, None], lanes.windows)
        next_window = _lowest_set_bit(remaining)
        path_done = lanes.active & (witness | exhausted | (undecided & free_only[lanes.row])
                                    | (~split & window_done & (next_window >= n_samples)))
        choose = lambda a, b, c: jnp.where(split, a, jnp.where(window_done, c, b))  # noqa: E731
        piece = jax.tree.map(choose, descend, climb,
                             _Piece(sample=next_window, level=jnp.zeros_like(piece.level),
                                    offset=jnp.zeros_like(piece.offset)))
        pending = jnp.where(split, descend_pending, jnp.where(window_done, 0, climb_pending))
        windows = jnp.where(split[:, None], lanes.windows, remaining)
        # Finished paths' verdicts written and idle lanes refilled at every step. Doing it
        # only once an eighth of the lanes waited (a branch) compiled every lane array's
        # kernels a second time, for about the same speed on CPU (benchmarks/RESULTS.md,
        # Decisions and negative results, "The bisection loop writes each lane array once per
        # step").
        target = jnp.where(path_done, lanes.row, n_rows)
        out = jax.tree.map(lambda o, v: o.at[target].set(v, mode="drop"), out, verdict)
        lanes = _Lanes(row=lanes.row, active=lanes.active & ~path_done, x=lanes.x,
                       windows=windows, piece=piece, pending=pending, verdict=verdict)
        lanes, next_item = refill(lanes, next_item)
        return lanes, next_item, out

    zeros = jnp.zeros(n_lanes, jnp.int32)
    lanes = _Lanes(row=zeros, active=jnp.zeros(n_lanes, bool),
                   x=jnp.zeros((n_lanes, x.shape[1]), dtype),
                   windows=jnp.zeros((n_lanes, failing_words.shape[1]), jnp.uint32),
                   piece=_Piece(zeros, zeros, zeros), pending=zeros,
                   verdict=_empty_verdict(n_lanes, dtype))
    # The lanes start idle: the first step tests nothing and refills them (a refill of its
    # own here compiled another copy of every lane array's kernels).
    busy = lambda state: state[0].active.any() | (state[1] < n_work)  # noqa: E731
    _, _, out = jax.lax.while_loop(busy, test_and_advance,
                                   (lanes, jnp.int32(0), _empty_verdict(n_rows, dtype)))
    return out


def _rows_first(chosen, with_place: bool = False):
    """The rows where ``chosen`` (shape (B,), bool) is true, in order, then the others in
    order (int32, shape (B,)), and how many are chosen: ``argsort(~chosen, stable=True)`` by a
    running count: on CPU the sort was a sizeable part of a certified search
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Rows first by a running
    count, not a sort"). ``with_place``: also each row's place in that order (the inverse)."""
    row = jnp.arange(chosen.shape[0], dtype=jnp.int32)
    running = jnp.cumsum(chosen, dtype=jnp.int32)
    before, count = running - chosen, running[-1]  # chosen rows before this one; all chosen
    place = jnp.where(chosen, before, count + row - before)
    order = jnp.zeros_like(row).at[place].set(row, unique_indices=True)
    return (order, count, place) if with_place else (order, count)


def search_spare(lengths):
    """cm, shape (): what a search's proofs keep beyond the margin (``check``'s ``spare``):
    2**-20 times the arm's reach, 8 to 16 float32 spacings there.

    A search's check and ``certify`` are separately compiled programs whose float32 rounding
    differs (one piece's bound by 7.7e-6 cm between two of them, on an arm of 80 cm), and a
    swarm drives its best paths to the edge of what its check proves: without a spare,
    ``certify`` found 2 of five-link-detour's 200 best paths undecided, a piece's bound 3.2e-6
    cm short (``benchmarks/RESULTS.md``, *Decisions and negative results*, "A search's proofs
    keep a spare").
    """
    return 2.0**-20 * jnp.sum(lengths)


def screens_windows(spec: ProblemSpec) -> bool:
    """Whether ``check`` screens the windows (a world with polygon slots:
    ``_screened_window_pass``) rather than drift-testing every one (circles alone:
    ``_dense_window_pass``); static, from the spec's capacities."""
    _, polygon_slots, _ = spec.capacities
    return polygon_slots > 0


def check(spec: ProblemSpec, arrays: ProblemArrays, x, prove=None, free_only=None,
          spare=0.0) -> CertifiedCheck:
    """The certified check of paths (module docstring).

    Args:
      spec: the problem's static part (degree, n_samples, certify_budget and capacities are
        read).
      arrays: the problem's data (certify_tol and margin, cm, may be traced).
      x: free parameters, shape (B, n_free).
      prove: optional, shape (B,), bool: the paths to prove. The others get stage 0 only:
        colliding if a sample finds a witness, else neither free nor colliding, with violation
        inf (a search skips the paths that could not change it: ``pso.Swarm.bar``).
      free_only: optional, shape (B,), bool: paths whose bisection stops at the first piece
        that is not free (a witness or undecided): only whether they are free matters, and
        their violation is what was found by then.
      spare: cm (may be traced), below ``certify_tol``: a window or piece is proved free only
        when its bound keeps the margin plus ``spare``, and one within the tolerance of that
        is undecided (``search_spare``: what a search asks for).

    Returns:
      ``CertifiedCheck`` of arrays of shape (B,).
    """
    degree, n_samples, budget = spec.degree, spec.n_samples, spec.certify_budget
    lengths, world, start, goal = arrays.lengths, arrays.world, arrays.start, arrays.goal
    motion = _Motion(lengths, world, start, goal, x)
    dtype = x.dtype
    step = 1.0 / (n_samples - 1)
    tol = jnp.asarray(arrays.certify_tol, dtype)
    margin = jnp.asarray(arrays.margin, dtype)
    proof_margin = margin + jnp.asarray(spare, dtype)  # what the proofs keep
    circles_only = not screens_windows(spec)  # which window pass (module docstring)
    if circles_only:
        nearest, closest = path.run_fold(_nearest_fold(lengths, world, x), start, goal, x,
                                         degree, n_samples)
    else:
        clearances = _sample_clearances(lengths, world, start, goal, x, degree, n_samples)
        nearest = clearances.min(axis=0)
        closest = jnp.argmin(clearances, axis=0).astype(jnp.int32)
    sample_witness = ~(nearest >= 0)
    unproved = ~sample_witness & (False if prove is None else ~prove)
    open_ = ~sample_witness & ~unproved
    if circles_only:
        windows = _dense_window_pass(motion, *_rows_first(open_), degree, n_samples,
                                     proof_margin)
    else:
        windows = _screened_window_pass(motion, clearances, open_, degree, n_samples,
                                        proof_margin)
    needs_work = open_ & (windows.failing != 0).any(axis=1)

    work_rows, n_work = _rows_first(needs_work)
    stop_early = jnp.zeros(x.shape[:1], bool) if free_only is None else free_only
    bisect = functools.partial(
        _bisect, motion, _Work(windows.failing, closest, stop_early, work_rows, n_work),
        jnp.asarray(_derivative_tables(degree, n_samples), dtype), step, tol, margin,
        proof_margin, budget)
    few, many = min(FEW_LANES, x.shape[0]), min(LANES, x.shape[0])
    few_paths = _few_paths()
    if few == many or x.shape[0] <= few_paths:  # never more than few_paths to bisect
        out = bisect(few)
    else:  # a wide loop runs as long as its slowest path: for a few paths, a narrow one
        out = jax.lax.cond(n_work <= few_paths, lambda: bisect(few), lambda: bisect(many))

    exhausted = needs_work & out.exhausted
    decided = needs_work & ~exhausted
    colliding = sample_witness | (decided & out.witness)
    free = open_ & ~(needs_work & (out.witness | out.undecided | out.exhausted))
    open_pieces = out.violation + jnp.where(exhausted, tol * step, 0.0)
    violation = jnp.where(sample_witness, margin - nearest,
                          jnp.where(unproved, jnp.inf, jnp.where(needs_work, open_pieces, 0.0)))
    proved = jnp.minimum(-windows.worst_passed, jnp.where(needs_work, out.proved, jnp.inf))
    seen = jnp.where(decided, jnp.minimum(nearest, out.nearest), nearest)
    clearance = jnp.where(free, proof_margin + proved, seen)
    return CertifiedCheck(violation=violation, free=free, colliding=colliding,
                          clearance=clearance, exhausted=exhausted,
                          pieces=jnp.where(needs_work, out.tested, 0))
