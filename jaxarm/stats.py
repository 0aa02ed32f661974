"""Binomial statistics for escape rates: Wilson intervals, Newcombe differences, Fisher's test
for independent samples and McNemar's exact test for paired ones.

Plain Python (no SciPy at run time); ``tests/test_stats.py`` checks every function against
SciPy on the same counts.
"""

from __future__ import annotations

import math
import operator
from typing import NamedTuple

Z_95 = 1.959963984540054


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (95 % by default).

    Examples:
      >>> [round(v, 4) for v in wilson_interval(3, 7)]
      [0.1582, 0.7495]
    """
    if trials <= 0:
        raise ValueError(f"trials must be > 0, got {trials}")
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must be in [0, {trials}], got {successes}")
    p = successes / trials
    denominator = 1 + z * z / trials
    center = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, center - half), min(1.0, center + half)


class Comparison(NamedTuple):
    """Two escape rates compared: ``a - b`` with a 95 % interval, Fisher's p-value (the two
    samples taken as independent) and McNemar's (the seeds paired)."""

    a: str  # label of the first
    b: str  # label of the second
    difference: float  # rate(a) - rate(b)
    interval: tuple[float, float]  # Newcombe's hybrid score interval for the difference
    p_value: float  # two-sided Fisher exact test of equal rates
    only_a: int  # paired seeds that a escaped and b did not
    only_b: int  # paired seeds that b escaped and a did not
    mcnemar_p: float  # two-sided exact McNemar test on those discordant seeds (NaN: none paired)

    def difference_text(self) -> str:
        """The difference and its interval in percentage points: ``+12.0% [+5.1%, +18.7%]``."""
        low, high = self.interval
        return f"{self.difference:+.1%} [{low:+.1%}, {high:+.1%}]"


def newcombe_interval(successes_a: int, trials_a: int, successes_b: int, trials_b: int,
                      z: float = Z_95) -> tuple[float, float]:
    """Interval for ``p_a - p_b`` from the two Wilson intervals (Newcombe 1998, method 10).

    Examples:
      >>> [round(v, 4) for v in newcombe_interval(56, 70, 48, 80)]
      [0.0524, 0.3339]
    """
    p_a, p_b = successes_a / trials_a, successes_b / trials_b
    low_a, high_a = wilson_interval(successes_a, trials_a, z)
    low_b, high_b = wilson_interval(successes_b, trials_b, z)
    below = math.sqrt((p_a - low_a) ** 2 + (high_b - p_b) ** 2)
    above = math.sqrt((high_a - p_a) ** 2 + (p_b - low_b) ** 2)
    return p_a - p_b - below, p_a - p_b + above


def fisher_exact(successes_a: int, trials_a: int, successes_b: int, trials_b: int) -> float:
    """Two-sided Fisher exact p-value for equal success rates in two groups.

    The p-value sums the hypergeometric probabilities of every table with the same margins
    that is no more likely than the observed one (SciPy's convention, with its relative
    tolerance of 1e-7 for ties).
    """
    successes = successes_a + successes_b
    total = trials_a + trials_b
    low, high = max(0, successes - trials_b), min(successes, trials_a)

    def log_probability(k: int) -> float:
        return (_log_choose(trials_a, k) + _log_choose(trials_b, successes - k)
                - _log_choose(total, successes))

    observed = log_probability(successes_a)
    cutoff = observed + math.log1p(1e-7)
    p = sum(math.exp(log_probability(k)) for k in range(low, high + 1)
            if log_probability(k) <= cutoff)
    return min(1.0, p)


def mcnemar_exact(only_a: int, only_b: int) -> float:
    """Two-sided exact McNemar p-value for paired success/failure outcomes: the binomial test
    of ``only_a`` successes in ``only_a + only_b`` discordant pairs against a rate of 1/2 (the
    pairs where both or neither succeeded say nothing about a difference). 1 without
    discordant pairs.

    Examples:
      >>> round(mcnemar_exact(9, 2), 4)
      0.0654
    """
    counts = []
    for name, value in (("only_a", only_a), ("only_b", only_b)):
        try:
            count = operator.index(value)  # ints and NumPy integers; not floats
        except TypeError:
            count = -1
        if isinstance(value, bool) or count < 0:
            raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
        counts.append(count)
    only_a, only_b = counts
    n = only_a + only_b
    tail = sum(math.exp(_log_choose(n, k) - n * math.log(2.0))
               for k in range(min(only_a, only_b) + 1))
    return min(1.0, 2.0 * tail)


def _log_choose(n: int, k: int) -> float:
    return math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1)
