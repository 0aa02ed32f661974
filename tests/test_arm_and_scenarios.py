"""Arm kinematics and scenario files."""

import math

import jax
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
    with pytest.raises(ValueError, match=r"needs a 3-link arm.* 2 links"):
        jaxarm.inverse_kinematics(jaxarm.Arm((1.0, 1.0)), 1, 0, 0)
    with pytest.raises(ValueError, match=r"pose.elbow must be \+1 or -1, got 0"):
        jaxarm.inverse_kinematics(ARM, 50, 0, 0, elbow=0)


def test_paper_case_1_postures_come_from_its_poses():
    problem = jaxarm.load_scenario("paper-case-1")
    np.testing.assert_allclose(jaxarm.inverse_kinematics(ARM, 50, -10, 0.201777, 1), problem.start,
                               atol=1e-12)
    np.testing.assert_allclose(jaxarm.inverse_kinematics(ARM, 50, 40, 0.886701, 1), problem.goal,
                               atol=1e-12)


def test_shipped_scenarios_load():
    names = jaxarm.available_scenarios()
    assert {"paper-case-1", "paper-case-2", "paper-case-3"} <= set(names)
    for name, description in names.items():
        problem = jaxarm.load_scenario(name)
        assert problem.name == name and description


def test_load_from_path_with_pose_and_overrides(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(
        '[arm]\nlengths = [30.0, 30.0, 20.0]\n'
        '[start]\npose = { x = 50.0, y = -10.0, phi = 0.0 }\n'
        '[goal]\njoints = [0.3, 1.2, -1.5]\n'
        '[search]\ndegree = 7\nsamples = 51\ninit_low = [-1, -2, -3, -4, -5, -6]\ninit_high = 9\n'
        '[[obstacles]]\ntype = "polygon"\nvertices = [[-10, 50], [-20, 60], [-5, 70]]\n'
    )
    problem = jaxarm.load_scenario(path, collision="certified")
    assert problem.name == "mine" and problem.degree == 7 and problem.n_samples == 51
    assert problem.collision == "certified" and len(problem.world.polygons) == 1
    np.testing.assert_allclose(problem.bounds()[0], [-1, -2, -3, -4, -5, -6])


@pytest.mark.parametrize(
    "text, message",
    [
        ("[arm\nlengths = [1]", r"bad.toml: malformed TOML: .*line 1"),
        ("[arm]\nlengths = [30.0]\nlenghts = 2\n[start]\njoints=[0]\n[goal]\njoints=[1]",
         r"unknown key in \[arm\]: 'lenghts'"),
        ("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\npose = {x = 100, y = 0}\n"
         "[goal]\njoints = [0, 0, 0]", r"start.pose \(x=100, y=0, phi=0.0\) is unreachable"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[search]\nsamples = 100", r"n_samples must be odd"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'circle'\ncenter = [50, 50]\nradius = -1",
         r"obstacles\[0\]: .*radius must be > 0, got -1.0"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'polygon'\nvertices = [[0, 50], [10, 60], [0, 60], [10, 50]]",
         r"obstacles\[0\]: .*not convex"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'box'\nmin = [0, 50]", r"obstacles\[0\] \(box\) is missing 'max'"),
        ("[arm]\nlengths = [30.0]\n[goal]\njoints = [1]", r"\[start\] must be a table"),
    ],
)
def test_malformed_scenarios_name_the_file_and_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(jaxarm.ScenarioError, match=message):
        jaxarm.load_scenario(path)


def test_unknown_scenario_lists_the_shipped_ones():
    with pytest.raises(ValueError, match=r"unknown scenario 'paper-case-9'; shipped .*paper-case-1"):
        jaxarm.load_scenario("paper-case-9")


@pytest.mark.parametrize(
    "world, message",
    [
        (dict(circles=[(0.0, 0.0)]), r"world.circles\[0\] must have 3 values"),
        (dict(boxes=[((1.0, 1.0), (0.0, 2.0))]), r"world.boxes\[0\] needs min < max"),
        (dict(polygons=[[(0, 0), (1, 1), (2, 2)]]), r"world.polygons\[0\] is degenerate"),
        (dict(polygons=[[(0, 0), (1, 0)]]), r"world.polygons\[0\] must be at least 3"),
    ],
)
def test_bad_worlds(world, message):
    with pytest.raises(ValueError, match=message):
        jaxarm.World(**world)


def test_float32_sincos_is_accurate_over_a_wide_range():
    from jaxarm.arm import sincos

    angle = np.linspace(-2000.0, 2000.0, 400_001, dtype=np.float32)
    sine, cosine = sincos(jax.numpy.asarray(angle))
    reference = angle.astype(np.float64)
    assert np.abs(np.asarray(sine) - np.sin(reference)).max() < 5e-7
    assert np.abs(np.asarray(cosine) - np.cos(reference)).max() < 5e-7
