"""Escape-rate statistics (``jaxarm.stats``) against SciPy and Newcombe's published examples."""

import pytest

from jaxarm import stats


@pytest.fixture(scope="module")
def scipy_stats():
    """``scipy.stats``, imported by the tests that use it: at collection it took 0.9 s in every
    xdist worker."""
    from scipy import stats as scipy_stats

    return scipy_stats


COUNTS = [(56, 70, 48, 80), (0, 10, 10, 10), (3, 7, 3, 7), (500, 500, 0, 500),
          (46, 100, 60, 100), (1, 3, 2, 9), (397, 500, 463, 500), (0, 5, 0, 8)]


@pytest.mark.parametrize("a, n, b, m", COUNTS)
def test_fisher_exact_matches_scipy(scipy_stats, a, n, b, m):
    reference = scipy_stats.fisher_exact([[a, n - a], [b, m - b]]).pvalue
    assert stats.fisher_exact(a, n, b, m) == pytest.approx(reference, rel=1e-9, abs=1e-300)


# Newcombe (1998), Statistics in Medicine 17: 873-890, Table II, method 10 (hybrid score)
NEWCOMBE = [((56, 70, 48, 80), (0.0524, 0.3339)), ((9, 10, 3, 10), (0.1705, 0.8090)),
            ((5, 56, 0, 29), (-0.0381, 0.1926)), ((0, 10, 0, 20), (-0.1611, 0.2775)),
            ((10, 10, 0, 20), (0.6791, 1.0000))]


@pytest.mark.parametrize("counts, published", NEWCOMBE)
def test_newcombe_interval_matches_the_published_examples(counts, published):
    low, high = stats.newcombe_interval(*counts)
    assert (round(low, 4), round(high, 4)) == published


@pytest.mark.parametrize("successes, trials", [(0, 10), (3, 7), (46, 100), (500, 500), (1, 3)])
def test_wilson_interval_matches_scipy(scipy_stats, successes, trials):
    reference = scipy_stats.binomtest(successes, trials).proportion_ci(0.95, method="wilson")
    low, high = stats.wilson_interval(successes, trials)
    assert low == pytest.approx(reference.low, abs=1e-12)
    assert high == pytest.approx(reference.high, abs=1e-12)


PAIRED = [(9, 2), (0, 0), (3, 3), (0, 7), (50, 30), (1, 0), (200, 180), (0, 1000), (4, 21)]


@pytest.mark.parametrize("only_a, only_b", PAIRED)
def test_mcnemar_exact_is_scipys_binomial_test_of_the_discordant_pairs(scipy_stats, only_a,
                                                                       only_b):
    n = only_a + only_b
    reference = scipy_stats.binomtest(only_a, n, 0.5).pvalue if n else 1.0
    assert stats.mcnemar_exact(only_a, only_b) == pytest.approx(reference, rel=1e-9,
                                                                 abs=1e-300)


def test_mcnemar_exact_takes_numpy_counts():
    import numpy as np

    assert stats.mcnemar_exact(np.int64(9), np.int32(2)) == stats.mcnemar_exact(9, 2)


def test_mcnemar_exact_names_a_bad_count():
    with pytest.raises(ValueError, match=r"only_b must be an integer >= 0, got -1"):
        stats.mcnemar_exact(3, -1)
    with pytest.raises(ValueError, match=r"only_a must be an integer >= 0, got 2.5"):
        stats.mcnemar_exact(2.5, 1)


def test_a_comparison_prints_its_difference_and_interval_in_points():
    comparison = stats.Comparison("B", "A", 0.12, (0.051, 0.187), 0.001, 7, 1, 0.07)
    assert comparison.difference_text() == "+12.0% [+5.1%, +18.7%]"


def test_bad_counts_name_the_argument():
    with pytest.raises(ValueError, match="trials must be > 0, got 0"):
        stats.wilson_interval(0, 0)
    with pytest.raises(ValueError, match=r"successes must be in \[0, 5\], got 7"):
        stats.wilson_interval(7, 5)
