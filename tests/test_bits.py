"""The certified check's bit masks and row orders (``jaxarm.checks.certified.bits``) against
NumPy."""

import jax
import numpy as np
import pytest

from jaxarm.checks.certified import bits


@pytest.mark.parametrize("size", [1, 7, 4000])
def test_chosen_rows_come_first_in_order_as_a_stable_sort_puts_them(rng, size):
    """``rows_first`` (a running count) against NumPy's stable argsort, on random masks and
    on all-chosen and none-chosen ones."""
    for chosen in (rng.random(size) < 0.3, np.ones(size, bool), np.zeros(size, bool)):
        rows, count, place = jax.jit(bits.rows_first, static_argnums=1)(chosen, True)
        np.testing.assert_array_equal(np.asarray(rows), np.argsort(~chosen, kind="stable"))
        assert int(count) == int(chosen.sum())
        np.testing.assert_array_equal(np.asarray(place)[np.asarray(rows)], np.arange(size))
        alone = jax.jit(bits.rows_first)(chosen)
        assert len(alone) == 2
        np.testing.assert_array_equal(np.asarray(alone[0]), np.asarray(rows))


def _random_words(rng):
    """Bits of shape (50, 101) (an empty row and a full one among them) and their words,
    packed by ``bits.packed``: shape (50, 4), uint32."""
    chosen = rng.random((50, 101)) < 0.3
    chosen[0], chosen[1] = False, True
    return chosen, np.asarray(jax.jit(bits.packed)(chosen))


def test_bits_pack_as_numpy_packs_them_little_endian(rng):
    """``packed`` against NumPy's ``packbits`` (little bit order), read as uint32."""
    chosen, words = _random_words(rng)
    assert words.shape == (50, 4) and words.dtype == np.uint32
    padded = np.pad(chosen, ((0, 0), (0, 27)))
    expected = np.packbits(padded.reshape(50, 4, 32), axis=-1, bitorder="little")
    np.testing.assert_array_equal(words, expected.view("<u4")[..., 0])


def test_set_bits_are_found_by_rank(rng):
    """``nth_set_bit`` against the positions of the set bits (``np.nonzero``) of every rank
    of random words."""
    _, words = _random_words(rng)
    flat = words.reshape(-1)
    word, rank = zip(*[(w, n) for w in range(len(flat)) for n in range(bin(flat[w]).count("1"))])
    found = jax.jit(bits.nth_set_bit)(flat[list(word)], np.asarray(rank, np.int32))
    positions = [np.nonzero((int(flat[w]) >> np.arange(32)) & 1)[0][n] for w, n in zip(word, rank)]
    np.testing.assert_array_equal(np.asarray(found), positions)


def test_the_lowest_set_bit_of_each_row(rng):
    """``lowest_set_bit`` against the first of NumPy's set positions of each row, and
    ``2**30`` for a row with none."""
    chosen, _ = _random_words(rng)
    chosen[2:10] = rng.random((8, 101)) < 0.02  # some sparse rows, their lowest bit far in
    chosen[2] = False
    words = np.asarray(jax.jit(bits.packed)(chosen))
    found = np.asarray(jax.jit(bits.lowest_set_bit)(words))
    assert found.dtype == np.int32
    expected = np.where(chosen.any(axis=1), np.argmax(chosen, axis=1), 1 << 30)
    np.testing.assert_array_equal(found, expected)
