"""Trajectories in seconds (``jaxarm.trajectory``): eqs. 8-9, limits, torques, export."""

import json

import jax
import numpy as np
import pytest

import jaxarm
from jaxarm import plot

PAPER_X = [66.7388, -28.1028, -9.8855]  # the paper's case II optimum (Table 3)


@pytest.fixture(scope="module")
def problem():
    return jaxarm.load_scenario("paper-case-2")


def dense_derivative(problem, x, order, n=200_001):
    """``theta^(order)(r)`` on a dense grid through ``joint_path`` (the basis form, float64),
    independent of the trajectory's power-form polynomials and their roots."""
    with jax.enable_x64(True):
        return np.asarray(jaxarm.joint_path(problem, np.asarray(x, np.float64),
                                            np.linspace(0.0, 1.0, n), order))


def test_at_is_the_path_derivative_over_the_duration_to_the_power(problem):
    duration = 2.5
    traj = jaxarm.Trajectory(problem, PAPER_X, duration=duration)
    t = np.linspace(0.0, duration, 41)
    state = traj.at(t)
    for order, values in enumerate(state):
        expected = np.asarray(jaxarm.joint_path(problem, np.float32(PAPER_X), t / duration,
                                                order)) / duration ** order
        scale = np.abs(expected).max()
        assert values.shape == (41, 3)
        np.testing.assert_allclose(values, expected, rtol=0, atol=2e-6 * scale)


def test_motion_is_rest_to_rest_between_the_postures(problem):
    traj = jaxarm.Trajectory(problem, PAPER_X, duration=1.7)
    ends = traj.at([0.0, 1.7])
    np.testing.assert_allclose(ends.position, [problem.start, problem.goal], atol=1e-12)
    for values in (ends.velocity, ends.acceleration):
        np.testing.assert_allclose(values, 0.0, atol=1e-12)


def test_bad_trajectories_and_times_are_refused(problem):
    for duration in (0.0, -1.0, float("nan"), float("inf"), "soon"):
        with pytest.raises(ValueError, match="duration"):
            jaxarm.Trajectory(problem, PAPER_X, duration=duration)
    with pytest.raises(ValueError, match=r"x must have 3 values"):
        jaxarm.Trajectory(problem, [1.0, 2.0], duration=1.0)
    traj = jaxarm.Trajectory(problem, PAPER_X, duration=2.0)
    for t in ([-0.1], [2.0001], [float("nan")]):
        with pytest.raises(ValueError, match=r"t must lie in \[0, duration = 2\] s"):
            traj.at(t)


@pytest.mark.parametrize("seed", range(6))
def test_min_duration_for_kinematic_limits_is_exact(problem, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-150, 150, problem.n_free)
    limits = dict(max_velocity=rng.uniform(0.5, 3.0), max_acceleration=rng.uniform(1.0, 10.0, 3),
                  max_jerk=rng.uniform(5.0, 50.0))
    for order, (name, limit) in enumerate(limits.items(), start=1):  # x: random, colliding
        duration = jaxarm.min_duration(problem, x, **{name: limit}, allow_colliding=True)
        peak = np.abs(dense_derivative(problem, x, order)).max(axis=0)
        exact = float(np.max((peak / limit) ** (1.0 / order)))  # the grid's peak: a lower bound
        assert exact <= duration <= exact * 1.002, (name, duration, exact)
    both = jaxarm.min_duration(problem, x, **limits, allow_colliding=True)
    assert both == pytest.approx(max(jaxarm.min_duration(problem, x, **{name: limit},
                                                         allow_colliding=True)
                                     for name, limit in limits.items()), rel=1e-12)


def test_min_duration_for_torque_limits_meets_them_and_is_tight(problem):
    limit = np.array([32.0, 16.0, 3.0])
    for x in (PAPER_X, [0.0, 0.0, 0.0], [-120.0, 80.0, 40.0]):  # the last two collide
        duration = jaxarm.min_duration(problem, x, max_torque=limit, allow_colliding=True)
        times = np.linspace(0.0, 1.0, 20_001)
        peak = np.abs(jaxarm.Trajectory(problem, x, duration).torques(times * duration))
        assert np.all(peak.max(axis=0) <= limit * (1 + 1e-9))
        faster = 0.98 * duration
        peak = np.abs(jaxarm.Trajectory(problem, x, faster).torques(times * faster))
        assert np.any(peak.max(axis=0) > limit)


def test_min_duration_refuses_impossible_or_missing_limits(problem):
    with pytest.raises(ValueError, match="needs at least one"):
        jaxarm.min_duration(problem, PAPER_X)
    with pytest.raises(ValueError, match=r"max_velocity\[1\] must be > 0, got -1.0"):
        jaxarm.min_duration(problem, PAPER_X, max_velocity=[1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match=r"max_jerk must have 3 values"):
        jaxarm.min_duration(problem, PAPER_X, max_jerk=[1.0, 1.0])
    with pytest.raises(ValueError, match=r"max_acceleration must be finite"):
        jaxarm.min_duration(problem, PAPER_X, max_acceleration=float("inf"))
    # joint 1 holds the whole arm: 25.4 N m at the start posture
    with pytest.raises(ValueError, match=r"max_torque\[0\] = 20 N m is at or below joint 1's "
                                         r"static gravity load 25.43 N m at the start posture"):
        jaxarm.min_duration(problem, PAPER_X, max_torque=[20.0, 50.0, 50.0])
    massless = problem.replace(arm=jaxarm.Arm(problem.arm.lengths))
    with pytest.raises(ValueError, match="arm.masses is not set"):
        jaxarm.min_duration(massless, PAPER_X, max_torque=50.0)
    with pytest.raises(ValueError, match="arm.masses is not set"):
        jaxarm.Trajectory(massless, PAPER_X, 1.0).torques([0.0])


def test_a_path_that_does_not_move_has_no_duration():
    problem = jaxarm.Problem(arm=jaxarm.Arm((30.0, 30.0, 20.0), gravity=0.0, masses=[1, 1, 1]),
                             start=[0.1, 0.2, 0.3], goal=[0.1, 0.2, 0.3])
    assert jaxarm.min_duration(problem, [0.0, 0.0, 0.0], max_velocity=1.0,
                               max_torque=1.0) == 0.0
    with pytest.raises(ValueError, match=r"got 0.0 \(min_duration's answer for a path that "
                                         r"does not move: any duration meets its limits\)"):
        jaxarm.Trajectory(problem, [0.0, 0.0, 0.0], 0.0)


def test_export_to_csv_and_json(problem, tmp_path):
    traj = jaxarm.Trajectory(problem, PAPER_X, duration=1.234)
    path = traj.to_csv(tmp_path / "t.csv", rate=50.0)
    header = path.read_text().splitlines()[0].split(",")
    assert header == (["t"] + [f"{p}{j}" for p in ("q", "dq", "ddq", "tau") for j in (1, 2, 3)])
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    assert rows.shape == (63, 13)  # 0, 0.02, ..., 1.22 and the end, 1.234
    np.testing.assert_allclose(rows[:, 0], np.append(np.arange(62) * 0.02, 1.234), atol=1e-12)
    state = traj.at(rows[:, 0])
    np.testing.assert_allclose(rows[:, 1:4], state.position, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rows[:, 10:], traj.torques(rows[:, 0]), rtol=1e-9, atol=1e-9)
    assert traj.to_json(tmp_path / "t.json", rate=50.0) == tmp_path / "t.json"
    record = json.loads(traj.to_json(rate=50.0))  # no path: the text
    assert record == json.loads((tmp_path / "t.json").read_text())
    assert traj.to_csv(rate=50.0) == path.read_text()
    assert record["duration"] == 1.234 and record["problem"] == "paper-case-2"
    np.testing.assert_allclose(record["columns"]["dq2"], rows[:, 5], rtol=1e-9, atol=1e-12)
    massless = jaxarm.Trajectory(problem.replace(arm=jaxarm.Arm(problem.arm.lengths)), PAPER_X,
                                 1.0)
    assert "tau1" not in massless.table(10.0) and len(massless.table(10.0)["t"]) == 11
    with pytest.raises(ValueError, match="rate must be > 0"):
        traj.to_csv(tmp_path / "bad.csv", rate=0.0)


def test_plot_profiles_draws_every_quantity_with_its_limits(problem):
    limited = problem.replace(joint_limits=[(4.0, 6.5), (1.0, 2.5), (0.0, 1.0)])
    duration = jaxarm.min_duration(limited, PAPER_X, max_velocity=1.0, max_torque=30.0)
    figure = plot.plot_profiles(jaxarm.Trajectory(limited, PAPER_X, duration), max_velocity=1.0,
                                max_torque=30.0)
    position, velocity, acceleration, torque = figure.axes
    assert len(position.lines) == 3 + 6 and len(velocity.lines) == 3 + 6
    assert len(acceleration.lines) == 3 and len(torque.lines) == 3 + 6
    assert max(np.abs(line.get_ydata()).max() for line in velocity.lines[:1]) == pytest.approx(
        1.0, rel=1e-3)


def test_min_duration_refuses_a_colliding_path_unless_asked(problem):
    colliding = [0.0, 0.0, 0.0]  # the straight path, through the obstacle
    with pytest.raises(ValueError, match=r"x is not collision-free in paper-case-2 \(certified "
                                         r"check, violation .*\).* allow_colliding=True"):
        jaxarm.min_duration(problem, colliding, max_velocity=1.0)
    assert jaxarm.min_duration(problem, colliding, max_velocity=1.0, allow_colliding=True) > 0
    assert jaxarm.min_duration(problem, PAPER_X, max_velocity=1.0) > 0  # proved free


def test_trajectory_sizes_that_would_not_compute_are_refused(problem):
    with pytest.raises(ValueError, match=r"duration must be at least 1e-06 s, got 1e-300"):
        jaxarm.Trajectory(problem, PAPER_X, duration=1e-300)
    with pytest.raises(ValueError, match=r"x\[0\] must be within \+-3.40282e\+38"):
        jaxarm.Trajectory(problem, [1e300, 0.0, 0.0], duration=1.0)
    traj = jaxarm.Trajectory(problem, PAPER_X, duration=1e6)
    with pytest.raises(ValueError, match=r"rate 1e\+06 Hz over 1e\+06 s gives 1e\+12 rows; at "
                                         r"most 1e\+07"):
        traj.table(rate=1e6)
    with pytest.raises(ValueError, match=r"gives inf rows"):
        traj.table(rate=1e305)
    with pytest.raises(ValueError, match=r"the limits \(max_velocity \[1e\+300, 1e\+300, "
                                         r"1e\+300\]\) allow the path a duration of .* below"):
        jaxarm.min_duration(problem, PAPER_X, max_velocity=1e300)
