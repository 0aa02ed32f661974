"""Bit masks and row orders for the certified check: sets of windows as uint32 words (bit
``i % 32`` of word ``i // 32`` stands for window i), and the rows a stage works on first.

Each is a few whole-array operations, with no sort and no scalar loop: the check calls them
on every batch, inside compiled loops.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def packed(bits):
    """Bits as words: bit ``i % 32`` of word ``i // 32`` is ``bits[:, i]``.

    Args:
      bits: shape (B, n), bool.

    Returns:
      Array of shape (B, ceil(n / 32)), uint32 (NumPy's ``packbits`` with
      ``bitorder="little"``, read as little-endian uint32).
    """
    n_words = -(-bits.shape[1] // 32)
    padded = jnp.pad(bits, ((0, 0), (0, 32 * n_words - bits.shape[1])))
    as_words = padded.reshape(bits.shape[0], n_words, 32).astype(jnp.uint32)
    return (as_words << jnp.arange(32, dtype=jnp.uint32)[None, None]).sum(axis=-1, dtype=jnp.uint32)


def nth_set_bit(words, n):
    """Index of the set bit of rank ``n`` (0: the lowest) of each word, by halving.

    Args:
      words: shape (m,), uint32.
      n: shape (m,), int32, below each word's count of set bits.

    Returns:
      Array of shape (m,), int32, in [0, 32).
    """
    index = jnp.zeros_like(n)
    for width in (16, 8, 4, 2, 1):
        below = jax.lax.population_count(words & jnp.uint32((1 << width) - 1)).astype(n.dtype)
        above = n >= below
        n = jnp.where(above, n - below, n)
        words = jnp.where(above, words >> width, words)
        index = index + jnp.where(above, width, 0)
    return index


def lowest_set_bit(words):
    """Index of the lowest set bit of each row of words (bit b of word w is index 32 w + b).

    Args:
      words: shape (n, n_words), uint32.

    Returns:
      Array of shape (n,), int32; ``2**30`` (above any index) where no bit is set.
    """
    lowest = words & (~words + jnp.uint32(1))
    trailing = jax.lax.population_count(lowest - jnp.uint32(1)).astype(jnp.int32)
    word = jnp.arange(words.shape[-1], dtype=jnp.int32)[None]
    index = jnp.where(words != 0, 32 * word + trailing, 1 << 30)
    return index.min(axis=-1)  # int32 with 64-bit types on too: the bisection loop carries it


def rows_first(chosen, with_place: bool = False):
    """The rows where ``chosen`` is true, in order, then the others in order:
    ``argsort(~chosen, stable=True)``, by a running count (on CPU a sort was a sizeable part
    of a certified search: ``benchmarks/RESULTS.md``, *Decisions and negative results*, "Rows
    first by a running count, not a sort").

    Args:
      chosen: shape (B,), bool.
      with_place: also return each row's place in that order (the inverse permutation).

    Returns:
      ``(order, count)``, or ``(order, count, place)`` with ``with_place``: ``order`` and
      ``place`` of shape (B,), int32; ``count`` int32 of shape (), how many rows are chosen.
    """
    row = jnp.arange(chosen.shape[0], dtype=jnp.int32)
    running = jnp.cumsum(chosen, dtype=jnp.int32)
    before, count = running - chosen, running[-1]  # chosen rows before this one; all chosen
    place = jnp.where(chosen, before, count + row - before)
    order = jnp.zeros_like(row).at[place].set(row, unique_indices=True)
    return (order, count, place) if with_place else (order, count)
