"""The feasible set, measured: how much of the initial range holds collision-free paths.

The initial swarm is drawn uniformly from the problem's init range, so if a share p of that
box is collision-free, a swarm of n particles starts with a free path with probability
``1 - (1 - p) ** n``: the predicted iteration-0 escape rate, which a study measures directly.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxarm._compile.padding import in_blocks
from jaxarm._validate import positive_int
from jaxarm.checks.evaluate import violation
from jaxarm.model.problem import Problem
from jaxarm.stats import wilson_interval

BLOCK = 4096  # paths per compiled call
MAX_DRAWS = 2**24  # paths drawn at once, in float64: bounds the draws' memory


class FeasibleFraction(NamedTuple):
    """The collision-free share of the init range, from ``n_paths`` uniform paths."""

    fraction: float
    interval: tuple[float, float]  # 95 % Wilson interval
    n_paths: int

    def start_escape(self, n_particles: int) -> tuple[float, tuple[float, float]]:
        """Predicted probability that a swarm of ``n_particles`` uniform particles already
        holds a free path at iteration 0, with the interval carried through (monotone)."""
        n_particles = positive_int("n_particles", n_particles)
        predict = lambda p: 1.0 - (1.0 - p) ** n_particles  # noqa: E731
        return predict(self.fraction), (predict(self.interval[0]), predict(self.interval[1]))


def feasible_fraction(problem: Problem, n_paths: int = 10_000, seed: int = 0
                      ) -> FeasibleFraction:
    """The share of the init range whose paths are collision-free in the problem's collision
    mode (and margin), estimated from ``n_paths`` uniform draws.

    Args:
      problem: the problem; its ``bounds()`` are the box sampled.
      n_paths: paths drawn (float64 NumPy ``default_rng(seed)``, then checked in blocks), at
        most ``MAX_DRAWS`` (2**24).
      seed: the draw's seed.

    Returns:
      ``FeasibleFraction``.

    Examples:
      >>> jaxarm.feasible_fraction(jaxarm.load_scenario("open-space"), 100).fraction
      1.0
    """
    n_paths = positive_int("n_paths", n_paths, maximum=MAX_DRAWS)
    low, high = problem.bounds()
    x = np.random.default_rng(seed).uniform(low, high, size=(n_paths, problem.n_free))
    # one program: every call has as many paths (``in_blocks``)
    free = int(np.sum(in_blocks(lambda rows: np.asarray(violation(problem, rows)), x,
                                min(BLOCK, n_paths)) == 0))
    return FeasibleFraction(fraction=free / n_paths, interval=wilson_interval(free, n_paths),
                            n_paths=n_paths)
