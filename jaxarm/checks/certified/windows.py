"""Stage 1 of the certified check: the windows around the samples.

Around every sample r_s lies the window ``|r - r_s| <= h / 2`` (h the sample spacing); the
windows cover [0, 1]. A window is proved when every link keeps the margin over it by the
cheap bounds of ``bounds.drift_shortfalls`` (how far the link can swing, or drift towards an
obstacle, from where it is at the sample); the windows that are not are recorded as a bit
mask (``bits``) for the bisection. Which pass runs depends on the world (static):

- circles alone (``dense_window_pass``): the drift test of every window;
- with polygons (``screened_window_pass``): a screen with no geometry first (the smallest
  clearance at the sample against the arm's largest swing), then the drift test of the
  windows the screen leaves. The screen proves a window only where the drift test would.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.checks.certified import bounds
from jaxarm.checks.certified.bits import nth_set_bit, packed, rows_first
from jaxarm.checks.certified.samples import Motion, derivative_tables
from jaxarm.model import path


class Windows(NamedTuple):
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


def _drift_fold(motion: Motion, degree, n_samples, margin) -> path.SampleFold:
    """Stage 1's drift test of every window, as a fold over the samples; ``finish`` returns
    the last ``_WindowPass``.

    The shortfalls alone: the nearest clearance at the samples comes from stage 0. With both,
    every link's distance had two consumers, and XLA's CPU backend materialised them (see
    ``benchmarks/RESULTS.md``, *Decisions and negative results*, "The window pass computes the
    shortfall alone").
    """
    lengths, world, start, goal, x = motion
    tables, window_radius = window_tables(degree, n_samples, x.dtype)

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
        shortfalls = bounds.drift_shortfalls(lengths, world, about_sample, window_radius,
                                             margin)
        return carry._replace(pending=functools.reduce(jnp.maximum, shortfalls))

    return path.SampleFold(init=_no_windows(x.shape[:-1], x.dtype, n_samples), step=add_sample,
                           finish=lambda carry: record(carry, jnp.int32(n_samples - 1)),
                           max_order=0)


def window_tables(degree: int, n_samples: int, dtype):
    """What both window passes expand the paths with: ``(tables, window_radius)``, the
    ``derivative_tables`` in ``dtype`` and a window's radius in r, shape () (half the sample
    spacing, widened as the bisection's piece radius)."""
    window_radius = 1.0 / (n_samples - 1) / 2 * (1.0 + 2.0**-20)
    return (jnp.asarray(derivative_tables(degree, n_samples), dtype),
            jnp.asarray(window_radius, dtype))


def dense_window_pass(motion: Motion, open_rows, n_open, degree, n_samples, margin,
                      window_chunk: int) -> Windows:
    """Stage 1 in a world of circles alone: the drift test of every window of the paths
    ``open_rows[:n_open]``, ``window_chunk`` paths at a time, each chunk a scan over the
    samples (its default size: ``benchmarks/RESULTS.md``, *Decisions and negative results*,
    "The window pass computes the shortfall alone" and "Not kept: other chunks for the dense
    window pass, and the swing screen as a row filter in worlds of circles").

    Args:
      motion: all paths, x of shape (B, n_free).
      open_rows: shape (B,), int32: the rows to pass first, then anything.
      n_open: int32 scalar.
      window_chunk: paths per scan (static).

    Returns:
      ``Windows``: the pass's values on the open rows, no failing window elsewhere.
    """
    x = motion.x
    n_rows = x.shape[0]
    chunk = min(window_chunk, n_rows)
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
    return Windows(failing=out.failing, worst_passed=out.worst_passed)


def window_swings(lengths, start, goal, x, tables, window_radius):
    """How far any point of the arm can move over each sample's window (cm), shape
    (n_samples, B): the last link's swing (``bounds.link_swings``), the largest of any
    link's. No geometry: the joints' Taylor coefficients about the sample alone."""
    def value(sample):
        rows = tables[sample.index]
        about_sample = [path.joint_angle_list(start, goal, x, rows[order], order)
                        for order in range(tables.shape[1])]  # order 0 unused: compiled away
        speed = [bounds.taylor_derivative_bound([order[j] for order in about_sample],
                                                window_radius)
                 for j in range(start.shape[0])]
        return bounds.link_swings(lengths, speed, window_radius)[-1]

    return path.sample_values(value, start, goal, x, tables.shape[1] - 1, tables.shape[0])


def screened_window_pass(motion: Motion, nearest, open_, degree, n_samples, margin,
                         swing_chunk: int, pair_chunk: int) -> Windows:
    """Stage 1 in a world with polygons (module docstring) on the paths where ``open_`` (shape
    (B,), bool), from stage 0's clearances ``nearest`` (shape (n_samples, B)).

    A window is proved first by its sample's clearance against the arm's largest swing
    (``window_swings``: no geometry), on the open paths only, ``swing_chunk`` paths at a time;
    only the windows that fail that are tested with the drift bound, compacted across paths,
    ``pair_chunk`` windows at a time (both static). Against circles alone the drift test costs
    so little per window that the screen and the compaction cost more than they save
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Windows screened by their
    swing").
    """
    lengths, world, start, goal, x = motion
    n_rows = x.shape[0]
    tables, window_radius = window_tables(degree, n_samples, x.dtype)
    open_rows, n_open, place = rows_first(open_, with_place=True)
    n_words = -(-n_samples // 32)
    rows_chunk = min(swing_chunk, n_rows)
    padded = jnp.concatenate([open_rows, jnp.zeros(-n_rows % rows_chunk, jnp.int32)])

    def screen_rows(state):  # open rows first..first + rows_chunk, in ``open_rows`` order
        first, hard_words, worst = state
        rows = jax.lax.dynamic_slice(padded, (first,), (rows_chunk,))
        shortfall = (window_swings(lengths, start, goal, x[rows], tables, window_radius)
                     - (nearest[:, rows] - margin))
        hard = ~(shortfall <= 0) & (first + jnp.arange(rows_chunk) < n_open)[None]  # NaN too
        passed = jnp.where(hard, -jnp.inf, shortfall).max(axis=0)
        return (first + rows_chunk,
                jax.lax.dynamic_update_slice(hard_words, packed(hard.T), (first, 0)),
                jax.lax.dynamic_update_slice(worst, passed, (first,)))

    _, hard_words, worst = jax.lax.while_loop(
        lambda state: state[0] < n_open, screen_rows,
        (jnp.int32(0), jnp.zeros((padded.shape[0], n_words), jnp.uint32),
         jnp.full(padded.shape, -jnp.inf, x.dtype)))
    hard_words = hard_words.reshape(-1)  # open rows' words, in ``open_rows`` order
    counts = jax.lax.population_count(hard_words).astype(jnp.int32)
    through = jnp.cumsum(counts)  # hard windows in the words up to each one
    n_hard = through[-1]
    chunk = min(pair_chunk, 32 * hard_words.shape[0])

    def pass_chunk(state):
        first, failing, worst = state
        rank = first + jnp.arange(chunk, dtype=jnp.int32)
        word = jnp.minimum(jnp.searchsorted(through, rank, side="right"), through.shape[0] - 1)
        bit = nth_set_bit(hard_words[word], rank - (through[word] - counts[word]))
        sample = jnp.minimum((word % n_words) * 32 + bit, n_samples - 1)
        xs, rows = x[padded[word // n_words]], tables[sample]
        about_sample = [path.joint_angle_list(start, goal, xs, rows[:, order], order,
                                              per_path=True)
                        for order in range(degree + 1)]
        drift = functools.reduce(jnp.maximum, bounds.drift_shortfalls(
            lengths, world, about_sample, window_radius, margin))
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
    return Windows(failing=jnp.where(open_[:, None], failing[place], jnp.uint32(0)),
                    worst_passed=jnp.where(open_, worst[place], -jnp.inf))
