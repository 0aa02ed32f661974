"""Polynomial joint paths: boundary conditions, the paper's eq. 10, derivatives, Simpson."""

import jax
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import jaxarm
from jaxarm.model import path

angles = st.floats(-7.0, 7.0, allow_nan=False)
coefficient = st.floats(-300.0, 300.0, allow_nan=False)


def _problem(start, goal, degree):
    return jaxarm.Problem(arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=start, goal=goal,
                          degree=degree)


@given(
    start=st.lists(angles, min_size=3, max_size=3),
    goal=st.lists(angles, min_size=3, max_size=3),
    degree=st.integers(6, 9),
    data=st.data(),
)
def test_boundary_conditions_hold_for_any_coefficients(start, goal, degree, data):
    problem = _problem(start, goal, degree)
    x = np.array(data.draw(st.lists(coefficient, min_size=problem.n_free,
                                    max_size=problem.n_free)))
    with jax.enable_x64(True):
        ends = np.array([0.0, 1.0])
        theta = np.asarray(jaxarm.joint_path(problem, x, ends))
        velocity = np.asarray(jaxarm.joint_path(problem, x, ends, order=1))
        acceleration = np.asarray(jaxarm.joint_path(problem, x, ends, order=2))
    np.testing.assert_allclose(theta[0], start, atol=1e-9)
    np.testing.assert_allclose(theta[1], goal, atol=1e-9)
    np.testing.assert_allclose(velocity, 0.0, atol=1e-8)
    np.testing.assert_allclose(acceleration, 0.0, atol=1e-7)


@given(start=st.lists(angles, min_size=3, max_size=3),
       goal=st.lists(angles, min_size=3, max_size=3),
       a6=st.lists(coefficient, min_size=3, max_size=3))
def test_degree_six_coefficients_are_the_papers_eq_10(start, goal, a6):
    problem = _problem(start, goal, 6)
    ti, tf, a6 = np.array(start), np.array(goal), np.array(a6)
    a5 = -3 * a6 - 6 * ti + 6 * tf
    a4 = 0.5 * (-9 * a6 - 5 * a5)
    a3 = tf - ti - a6 - a5 - a4
    expected = np.stack([ti, 0 * ti, 0 * ti, a3, a4, a5, a6], axis=-1)
    with jax.enable_x64(True):
        got = np.asarray(jaxarm.coefficients(problem, a6))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-9)


def test_free_parameters_are_ordered_by_power_then_joint():
    problem = _problem([0.1, 0.2, 0.3], [1.0, 1.1, 1.2], 7)
    x = np.array([1.0, 2.0, 3.0, 10.0, 20.0, 30.0])  # a6 of joints 1-3, then a7 of joints 1-3
    with jax.enable_x64(True):
        c = np.asarray(jaxarm.coefficients(problem, x))
    np.testing.assert_allclose(c[:, 6], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(c[:, 7], [10.0, 20.0, 30.0])


@pytest.mark.parametrize("order", [1, 2, 3])
def test_derivatives_match_finite_differences(order):
    problem = _problem([0.3, -1.0, 2.0], [1.5, 0.5, -0.5], 8)
    x = np.linspace(-40.0, 55.0, problem.n_free)
    r = np.linspace(0.1, 0.9, 9)
    eps = 1e-5
    with jax.enable_x64(True):
        lower = np.asarray(jaxarm.joint_path(problem, x, r - eps, order=order - 1))
        upper = np.asarray(jaxarm.joint_path(problem, x, r + eps, order=order - 1))
        exact = np.asarray(jaxarm.joint_path(problem, x, r, order=order))
    np.testing.assert_allclose(exact, (upper - lower) / (2 * eps), rtol=1e-6, atol=1e-5)


def test_simpson_weights_integrate_cubics_exactly():
    r = np.linspace(0.0, 1.0, 11)
    weights = path.simpson_weights(11)
    np.testing.assert_allclose(weights @ (4 * r**3 - r + 2), 1.0 - 0.5 + 2.0, rtol=1e-14)


def test_travelling_distance_is_the_arc_length_of_each_joint_curve():
    problem = _problem([0.0, 0.0, 0.0], [1.0, -2.0, 0.5], 6)
    x = np.array([30.0, -10.0, 5.0])
    with jax.enable_x64(True):
        # A dense chord-length polyline converges to the same arc length.
        r = np.linspace(0.0, 1.0, 200_001)
        theta = np.asarray(jaxarm.joint_path(problem, x, r))
        chords = np.sqrt(np.diff(r)[:, None] ** 2 + np.diff(theta, axis=0) ** 2).sum()
        simpson = float(jaxarm.travelling_distance(problem, x))
    assert simpson == pytest.approx(chords, rel=1e-6)


@given(degree=st.integers(7, 8), data=st.data())
def test_raise_degree_keeps_the_same_path(degree, data):
    problem = jaxarm.load_scenario("paper-case-2")
    x = np.array(data.draw(st.lists(st.floats(-200, 200), min_size=3, max_size=3)))
    higher = problem.replace(degree=degree)
    raised = jaxarm.raise_degree(x, 3, degree)
    assert raised.shape == (higher.n_free,)
    r = np.linspace(0, 1, 11)
    np.testing.assert_allclose(np.asarray(jaxarm.joint_path(higher, raised, r)),
                               np.asarray(jaxarm.joint_path(problem, x, r)), atol=1e-4)


def test_sample_values_are_the_value_at_every_sample():
    """``sample_values`` (each value written one step late) against the joint angles and speeds
    evaluated at all samples at once, for a batch of paths."""
    rng = np.random.default_rng(0)
    start, goal = np.float32([0.3, -0.2]), np.float32([1.1, 0.4])
    x = rng.normal(0.0, 1.0, (5, 2 * path.n_free_per_joint(7))).astype(np.float32)
    values = path.sample_values(lambda sample: (sample.derivatives[0][1],
                                                sample.derivatives[1][0] * sample.weight),
                                start, goal, x, 7, 11, max_order=1)
    r = np.linspace(0.0, 1.0, 11)
    # shape (paths, times, joints) = (5, 11, 2)
    angles = np.asarray(path.joint_angle_array(start, goal, x, path.basis_values(7, r, 0)))
    speeds = np.asarray(path.joint_angle_array(start, goal, x, path.basis_values(7, r, 1), 1))
    np.testing.assert_allclose(values[0], angles[..., 1].T, rtol=1e-6)
    np.testing.assert_allclose(values[1], (speeds[..., 0] * path.simpson_weights(11)).T,
                               rtol=1e-6)
