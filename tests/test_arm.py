"""Arm kinematics (``jaxarm.model.arm``)."""

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import jaxarm

ARM = jaxarm.Arm((30.0, 30.0, 20.0))


def test_forward_kinematics_is_the_papers_eqs_1_to_3():
    theta = np.array([0.3, -1.1, 0.7])
    positions = np.asarray(jaxarm.joint_positions(ARM.lengths, theta))
    x1, y1 = 30 * math.cos(0.3), 30 * math.sin(0.3)
    x2, y2 = x1 + 30 * math.cos(-0.8), y1 + 30 * math.sin(-0.8)
    x3, y3 = x2 + 20 * math.cos(-0.1), y2 + 20 * math.sin(-0.1)
    np.testing.assert_allclose(positions, [[0, 0], [x1, y1], [x2, y2], [x3, y3]], atol=1e-5)


def test_forward_kinematics_batches_over_any_leading_shape():
    theta = np.random.default_rng(0).uniform(-3, 3, (4, 5, 3))
    batched = np.asarray(jaxarm.joint_positions(ARM.lengths, theta))
    assert batched.shape == (4, 5, 4, 2)
    np.testing.assert_allclose(batched[2, 3], jaxarm.joint_positions(ARM.lengths, theta[2, 3]),
                               atol=1e-5)


@given(x=st.floats(-75, 75), y=st.floats(-75, 75), phi=st.floats(-math.pi, math.pi),
       elbow=st.sampled_from([1, -1]))
def test_inverse_kinematics_round_trips(x, y, phi, elbow):
    try:
        theta = jaxarm.inverse_kinematics(ARM, x, y, phi, elbow)
    except ValueError as error:
        assert "unreachable" in str(error)
        wrist = math.hypot(x - 20 * math.cos(phi), y - 20 * math.sin(phi))
        assert wrist > 60 - 1e-9
        return
    assert np.sign(theta[1]) in (elbow, 0)
    with jax.enable_x64(True):
        end = np.asarray(jaxarm.joint_positions(ARM.lengths, theta))[-1]
    np.testing.assert_allclose(end, [x, y], atol=1e-7)
    assert math.remainder(theta.sum() - phi, 2 * math.pi) == pytest.approx(0, abs=1e-9)


def test_inverse_kinematics_errors():
    with pytest.raises(ValueError, match=r"pose \(x=100, y=0, phi=0\) is unreachable"):
        jaxarm.inverse_kinematics(ARM, 100, 0, 0)
    with pytest.raises(ValueError, match=r"needs an arm of 3 or more links, got arm.lengths "
                                         r"with 2; give the joints"):
        jaxarm.inverse_kinematics(jaxarm.Arm((1.0, 1.0)), 1, 0, 0)
    with pytest.raises(ValueError, match=r"pose.elbow must be \+1 or -1, got 0"):
        jaxarm.inverse_kinematics(ARM, 50, 0, 0, elbow=0)
    with pytest.raises(ValueError, match=r"pose \(x=1e\+300, y=0, phi=0\) is unreachable"):
        jaxarm.inverse_kinematics(ARM, 1e300, 0, 0)  # no OverflowError squaring it
    for wrong in ("a", True, None, [1.0, 2.0]):  # named, not float()'s own words
        message = f"pose.phi must be a number, got {wrong!r}"
        with pytest.raises(ValueError, match=re.escape(message)):
            jaxarm.inverse_kinematics(ARM, 50, 0, wrong)
    with pytest.raises(ValueError, match=r"pose.y must be finite, got nan"):
        jaxarm.inverse_kinematics(ARM, 50, float("nan"), 0)
    theta = jaxarm.inverse_kinematics(ARM, np.float32(50), np.array(10.0), 0)  # any real scalar
    np.testing.assert_allclose(theta, jaxarm.inverse_kinematics(ARM, 50, 10, 0))


@pytest.mark.parametrize("n_links", [4, 5, 10])
def test_poses_of_longer_arms_round_trip(rng, n_links):
    """Random reachable poses (those of random postures): ``joint_positions`` of the solution
    (float32, as the search computes) reaches each within 1e-4 cm and 1e-6 rad."""
    arm = jaxarm.Arm(tuple(rng.uniform(5, 25, n_links)))
    for _ in range(8):
        posture = rng.uniform(-2, 2, n_links)
        end = np.asarray(jaxarm.joint_positions(arm.lengths, posture.astype(np.float64)))[-1]
        phi = float(np.sum(posture))
        for elbow in (1, -1):
            theta = jaxarm.inverse_kinematics(arm, *end, phi, elbow)
            reached = np.asarray(jaxarm.joint_positions(arm.lengths, theta.astype(np.float32)))
            np.testing.assert_allclose(reached[-1], end, atol=1e-4)
            assert math.remainder(theta.sum() - phi, 2 * math.pi) == pytest.approx(0, abs=1e-6)


def test_a_redundant_arm_takes_the_solution_near_the_posture_given(rng):
    arm = jaxarm.Arm((20.0,) * 6)
    for _ in range(5):
        posture = rng.uniform(-1.5, 1.5, 6)
        with jax.enable_x64(True):
            end = np.asarray(jaxarm.joint_positions(arm.lengths, posture))[-1]
        near = posture + rng.normal(0, 0.05, 6)
        theta = jaxarm.inverse_kinematics(arm, *end, posture.sum(), near=near)
        assert np.abs(theta - posture).max() < 0.1  # the posture itself, not another one
        far = jaxarm.inverse_kinematics(arm, *end, posture.sum(), near=-posture)
        with jax.enable_x64(True):
            np.testing.assert_allclose(np.asarray(jaxarm.joint_positions(arm.lengths, far))[-1],
                                       end, atol=1e-7)


def test_poses_of_longer_arms_refuse_what_they_cannot_reach():
    arm = jaxarm.Arm((10.0,) * 10)
    with pytest.raises(ValueError, match=r"pose \(x=101, y=0, phi=0\) is unreachable: the wrist at "
                                         r"\(91, 0\) is 91 cm from the base, outside \[0, 90\]"):
        jaxarm.inverse_kinematics(arm, 101, 0, 0)
    with pytest.raises(ValueError, match=r"pose.near must have 10 values, got 3"):
        jaxarm.inverse_kinematics(arm, 50, 0, 0, near=[0, 0, 0])
    hooked = jaxarm.Arm((50.0, 5.0, 5.0, 5.0))  # the wrist cannot come within 35 cm of the base
    with pytest.raises(ValueError, match=r"outside \[40, 60\]"):
        jaxarm.inverse_kinematics(hooked, 0.0, 10.0, 0.0)


def test_float32_sincos_is_accurate_over_a_wide_range():
    from jaxarm.model.arm import sincos

    angle = np.linspace(-2000.0, 2000.0, 400_001, dtype=np.float32)
    sine, cosine = sincos(jax.numpy.asarray(angle))
    reference = angle.astype(np.float64)
    assert np.abs(np.asarray(sine) - np.sin(reference)).max() < 5e-7
    assert np.abs(np.asarray(cosine) - np.cos(reference)).max() < 5e-7


@pytest.mark.parametrize("form", [list, tuple, np.asarray, jnp.asarray])
def test_joint_positions_takes_any_sequence_of_numbers(form):
    expected = np.asarray(jaxarm.joint_positions(np.array([30.0, 30.0, 20.0]),
                                                 np.array([0.1, 0.2, 0.3])))
    np.testing.assert_array_equal(
        jaxarm.joint_positions(form([30, 30, 20]), form([0.1, 0.2, 0.3])), expected)
    np.testing.assert_allclose(expected[-1], [75.01693, 23.153458], rtol=1e-6)


def test_joint_positions_of_one_link_takes_one_number_and_names_bad_shapes():
    np.testing.assert_allclose(jaxarm.joint_positions([30], 0.5),
                               [[0.0, 0.0], [30 * np.cos(0.5), 30 * np.sin(0.5)]], rtol=1e-6)
    with pytest.raises(ValueError, match=r"theta must have shape \(\.\.\., 2\) for 2 links"):
        jaxarm.joint_positions([30, 30], [0.1])
    with pytest.raises(ValueError, match="theta must be real numbers, got 'a'"):
        jaxarm.joint_positions([30], "a")
    with pytest.raises(ValueError, match=r"lengths must have shape \(n_joints,\)"):
        jaxarm.joint_positions([[30]], [0.1])
