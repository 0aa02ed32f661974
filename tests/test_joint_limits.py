"""Joint limits (``jaxarm.checks.joint_limits``): sampled and certified, against a dense evaluation."""

import jax
import numpy as np
import pytest

import jaxarm
from jaxarm.checks import joint_limits
from jaxarm.model import path
from jaxarm.testing import oracle_path_collides

# The paper's case II: joint 1 moves from 5.78 to 5.43 rad, joint 2 from 1.15 to 2.02 rad.
LIMITS = [(4.0, 6.5), (0.9, 2.6), (0.2, 1.0)]


@pytest.fixture(scope="module")
def limited():
    return jaxarm.load_scenario("paper-case-2").replace(joint_limits=LIMITS)


def dense_excess(problem, x, n=2001):
    """Largest excess over the limits at n points of r (float64), per path: a lower bound on
    the true excess; shape (...,)."""
    with jax.enable_x64(True):
        theta = np.asarray(jaxarm.joint_path(problem, np.asarray(x, np.float64),
                                             np.linspace(0.0, 1.0, n)))
    low, high = np.asarray(problem.joint_limits).T
    return np.maximum(np.maximum(theta - high, low - theta), 0.0).max(axis=(-2, -1))


def test_bernstein_bounds_contain_the_path_and_are_tight():
    rng = np.random.default_rng(0)
    start, goal = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
    x = rng.uniform(-300, 300, (100, 3))
    tables = joint_limits.bernstein_tables(6, 101)  # (400, 7, 2)
    n_pieces = tables.shape[0]
    with jax.enable_x64(True):
        bounds = np.asarray(path.joint_angle_array(start, goal, x, tables.reshape(-1, 2))
                            ).reshape(100, n_pieces, 7, 3)
        r = np.linspace(0.0, 1.0, n_pieces * 16 + 1)
        theta = np.asarray(path.joint_angle_array(start, goal, x, path.basis_values(6, r)))
        curvature = np.abs(np.asarray(path.joint_angle_array(start, goal, x,
                                                             path.basis_values(6, r, 2), 2)))
    inside = theta[:, :-1].reshape(100, n_pieces, 16, 3)
    assert np.all(inside <= bounds.max(axis=2)[:, :, None] + 1e-12)
    assert np.all(inside >= bounds.min(axis=2)[:, :, None] - 1e-12)
    np.testing.assert_allclose(bounds[:, :, 0], inside[:, :, 0], atol=1e-12)  # ends exact
    # The module's claim: the bound is within w^2 / 8 max|theta''| of the curve.
    gap = bounds.max(axis=(1, 2)) - theta.max(axis=1)
    assert np.all(gap <= (1.0 / n_pieces) ** 2 / 8 * curvature.max(axis=1) + 1e-12)


@pytest.fixture(scope="module")
def open_space(limited):
    """Only the limits can fail. The certified tests of the limits run here: with obstacles,
    most wild paths are refused for a collision anyway, whatever the limits' check says."""
    return limited.replace(world=jaxarm.World())


def test_certified_limits_never_call_a_leaving_path_inside(open_space):
    rng = np.random.default_rng(1)
    x = rng.uniform(-400, 400, (3000, 3)).astype(np.float32)  # 3000: the next test's program
    truth = dense_excess(open_space, x)
    certificate = jaxarm.certify(open_space, x)
    assert not np.any(certificate.free & (truth > 0))  # no false "inside"
    excess = np.asarray(jaxarm.violation(open_space, x))  # no obstacle: the limits' alone
    assert np.all(excess[truth > 1e-6] > 0)
    assert np.all(np.asarray(certificate.colliding)[truth > 1e-3])  # found at the piece ends


def test_certified_limits_prove_paths_that_stay_a_little_inside(open_space):
    rng = np.random.default_rng(3)
    x = rng.uniform(-60, 60, (3000, 3)).astype(np.float32)
    with jax.enable_x64(True):
        theta = np.asarray(jaxarm.joint_path(open_space, np.float64(x),
                                             np.linspace(0, 1, 2001)))
    low, high = np.asarray(LIMITS).T
    slack = np.minimum(theta - low, high - theta).min(axis=(-2, -1))
    certificate = jaxarm.certify(open_space, x)
    clear = slack >= 1e-3
    assert clear.sum() > 300 and (slack < 0).sum() > 300, (clear.sum(), (slack < 0).sum())
    assert np.all(np.asarray(certificate.free)[clear])
    assert not np.any(np.asarray(certificate.free)[slack < 0])


def test_sampled_limits_check_the_samples_only(limited):
    sampled = limited.replace(collision="sampled")
    rng = np.random.default_rng(2)
    x = rng.uniform(-400, 400, (2000, 3)).astype(np.float32)
    at_samples = dense_excess(sampled, x, n=101)
    excess = np.asarray(jaxarm.violation(sampled, x)) - np.asarray(
        jaxarm.violation(sampled.replace(joint_limits=None), x))
    np.testing.assert_array_equal(excess > 1e-5, at_samples > 1e-5)
    assert np.all(np.asarray(jaxarm.fitness(sampled, x))[at_samples > 1e-5] == 0)


def test_a_search_under_limits_keeps_every_joint_inside(limited):
    tight = limited.replace(joint_limits=[(4.0, 6.5), (0.9, 2.6), (0.2, 0.8)])
    unconstrained_best = [57.787106, -20.26278, -23.455057]  # found by solve without limits
    assert dense_excess(tight, unconstrained_best) > 0.1  # joint 3 reaches 0.957 rad
    result = jaxarm.solve(tight, "A", n_particles=12, n_iters=30, n_restarts=4, seed=0,
                          constraint="feasibility")
    assert result.feasible and dense_excess(tight, result.best_x) == 0.0
    # Among the obstacles, a path that clears them but leaves the limits is not free either.
    certificate = jaxarm.certify(tight, [result.best_x, unconstrained_best])
    np.testing.assert_array_equal(certificate.free, [True, False])
    np.testing.assert_array_equal(certificate.colliding, [False, True])
    assert not oracle_path_collides(tight, [unconstrained_best], 2001)[0]  # shapely, dense


def test_bad_limits_and_postures_outside_them_are_refused(limited):
    for value, message in [([(0.0, 1.0)] * 2, "one \\(low, high\\) pair per joint \\(3\\)"),
                           ([(4.0, 6.5), (2.6, 0.9), (0.2, 1.0)],
                            r"joint_limits\[1\] must have low < high, got \(2.6, 0.9\)"),
                           ([(4.0, 6.5), (0.9, float("inf")), (0.2, 1.0)],
                            r"joint_limits\[1\]\[1\] must be finite"),
                           ([(4.0, 6.5, 7.0), (0.9, 2.6), (0.2, 1.0)],
                            r"joint_limits\[0\] must have 2 values"),
                           (3.0, "joint_limits must be a list of \\(low, high\\) pairs")]:
        with pytest.raises(ValueError, match=message):
            limited.replace(joint_limits=value)
    with pytest.raises(ValueError, match=r"goal joint 2 is 2.0154 rad, outside "
                                         r"joint_limits\[1\] = \(0.9, 2.0\)"):
        limited.replace(joint_limits=[(4.0, 6.5), (0.9, 2.0), (0.2, 1.0)])


def test_limits_round_trip_through_scenario_files(limited, tmp_path):
    loaded = jaxarm.load_scenario(jaxarm.save_scenario(limited, tmp_path / "limited.toml"))
    assert loaded == limited and loaded.joint_limits == tuple(map(tuple, LIMITS))
    assert "limits" in limited.summary()
