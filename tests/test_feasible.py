"""The feasible share of the init range (``jaxarm.feasible_fraction``) and what it predicts."""

import numpy as np
import pytest

import jaxarm
from jaxarm import stats, study
from jaxarm.testing import oracle_path_collides


def test_feasible_fraction_agrees_with_an_independent_monte_carlo_estimate():
    problem = jaxarm.load_scenario("paper-case-2", collision="sampled")
    ours = jaxarm.feasible_fraction(problem, n_paths=3000, seed=0)
    # other draws, checked by shapely at the same 101 samples (no jaxarm kernel involved)
    low, high = problem.bounds()
    x = np.random.default_rng(12345).uniform(low, high, size=(3000, problem.n_free))
    free = int(np.sum(~oracle_path_collides(problem, x, problem.n_samples)))
    assert 0.02 < ours.fraction < 0.08 and ours.n_paths == 3000
    assert ours.interval == stats.wilson_interval(round(ours.fraction * 3000), 3000)
    # two independent estimates of one proportion: Fisher's test does not tell them apart
    assert stats.fisher_exact(round(ours.fraction * 3000), 3000, free, 3000) > 0.001


def test_the_predicted_start_escape_matches_the_measured_iteration_zero_rate():
    problem = jaxarm.load_scenario("paper-case-2", collision="sampled")
    share = jaxarm.feasible_fraction(problem, n_paths=4000, seed=1)
    predicted, (low, high) = share.start_escape(8)
    assert predicted == pytest.approx(1 - (1 - share.fraction) ** 8)
    result = study.escape_study(problem, ["A"], n_restarts=300, n_particles=8, n_iters=2)
    measured = result.method("A").start_escape_rate()
    measured_low, measured_high = stats.wilson_interval(round(measured * 300), 300)
    assert measured_low <= high and low <= measured_high  # the two intervals overlap
    assert result.method("A").summary()["start_escape_rate"] == measured


def test_open_space_is_all_free_and_bad_sizes_name_the_argument():
    # 100 paths: the program of feasible_fraction's docstring example
    share = jaxarm.feasible_fraction(jaxarm.load_scenario("open-space"), n_paths=100)
    assert share.fraction == 1.0 and share.start_escape(20)[0] == 1.0
    with pytest.raises(ValueError, match="n_paths must be"):
        jaxarm.feasible_fraction(jaxarm.load_scenario("open-space"), n_paths=0)
    with pytest.raises(ValueError, match="n_paths must be <= 16777216, got 1000000000"):
        jaxarm.feasible_fraction(jaxarm.load_scenario("open-space"), n_paths=10**9)
    with pytest.raises(ValueError, match="n_particles must be"):
        share.start_escape(0)
