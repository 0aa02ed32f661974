"""Batches padded to a few sizes, so that a handful of compiled programs serve every batch.

Every batched entry point of the package (``fitness``, ``violation``, ``certify``,
``travelling_distance``, ``refine``, ``feasible_fraction``, the certified check's window
pass, the restart loop's blocks) pads its rows with ``padded_size`` or runs them through
``on_padded_rows`` / ``in_blocks``.
"""

from __future__ import annotations

import math

import jax
import numpy as np

SMALL_BATCH = 64  # the smallest padded batch of ``fitness``, ``violation`` and ``certify``
LARGE_BLOCK = 4096  # batches above this are padded to a multiple of it


def padded_size(n_rows: int, smallest: int = SMALL_BATCH) -> int:
    """The batch size that ``n_rows`` paths are padded to before a compiled call: a power of
    two >= ``smallest`` up to ``LARGE_BLOCK``, above it a multiple of ``LARGE_BLOCK``.

    An empty batch is run as ``smallest`` paths (all cut away again). A handful of compiled
    programs then serve every batch size, for under twice the work.
    """
    if n_rows > LARGE_BLOCK:
        return round_up(n_rows, LARGE_BLOCK)
    return max(smallest, 1 << (max(n_rows, 1) - 1).bit_length())


def on_padded_rows(kernel, x, smallest: int = SMALL_BATCH):
    """``kernel(rows)`` for x's paths as rows (B, n_free), padded with copies of the first path
    to ``padded_size(B, smallest)`` rows; each field of the result, shape (B_padded, *rest),
    cut back to shape x.shape[:-1] + rest.

    Rows are independent (no path's result depends on the others in its batch). A traced x
    (inside the caller's own jit or vmap) is not padded: its program is compiled once anyway.
    """
    if isinstance(x, jax.core.Tracer):
        rows = x.reshape((math.prod(x.shape[:-1]), x.shape[-1]))  # -1 fails on empty batches
        return jax.tree.map(lambda a: a.reshape(x.shape[:-1] + a.shape[1:]), kernel(rows))
    # Padded and cut on the host: done with jax.numpy, each of these steps compiled a small
    # program of its own in every new process (benchmarks/RESULTS.md, "Persistent
    # compilation cache").
    rows = np.asarray(x).reshape((math.prod(x.shape[:-1]), x.shape[-1]))
    n_rows = rows.shape[0]
    first = rows[:1] if n_rows else np.zeros((1, rows.shape[1]), rows.dtype)
    rows = np.concatenate([rows, np.repeat(first, padded_size(n_rows, smallest) - n_rows, 0)])

    def cut(a):
        shape = x.shape[:-1] + a.shape[1:]
        if isinstance(a, jax.core.Tracer):  # a caller's jit holds x as a constant
            return a[:n_rows].reshape(shape)
        return jax.device_put(np.asarray(a)[:n_rows].reshape(shape))

    return jax.tree.map(cut, kernel(rows))


def in_blocks(kernel, rows: np.ndarray, block: int) -> np.ndarray:
    """``kernel`` over ``rows`` (B, ...) in blocks of ``block`` rows, the last block padded
    with copies of the first row, so that every call has one shape (one compiled program);
    the results, shape (B, ...), concatenated with the padding cut away. For work too large
    for one call (memory, or a progress bar that moves)."""
    n_rows = rows.shape[0]
    padded = np.concatenate([rows, np.repeat(rows[:1], -n_rows % block, axis=0)])
    return np.concatenate([kernel(padded[start:start + block])
                           for start in range(0, n_rows, block)])[:n_rows]


def round_up(n: int, multiple: int) -> int:
    """The smallest multiple of ``multiple`` >= ``n``."""
    return -(-n // multiple) * multiple


def equal_chunk_length(n: int, most: int) -> int:
    """Items per call when ``n`` are run in the fewest chunks of at most ``most``, as equal as
    possible: 1000 in chunks of at most 500 -> 500, 1001 -> 334 (334, 334, 333)."""
    n_chunks = -(-n // most)
    return -(-n // n_chunks)
