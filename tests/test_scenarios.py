"""Scenario files and the loader (``jaxarm.io.scenario_files``)."""

import numpy as np
import pytest

import jaxarm
from jaxarm.choices import MAX_DEGREE
from jaxarm.io import scenario_files
from jaxarm.testing import dense_clearance

ARM = jaxarm.Arm((30.0, 30.0, 20.0))
MINIMAL = "[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"


def test_paper_case_1_postures_come_from_its_poses():
    problem = jaxarm.load_scenario("paper-case-1")
    np.testing.assert_allclose(jaxarm.inverse_kinematics(ARM, 50, -10, 0.201777, 1), problem.start,
                               atol=1e-12)
    np.testing.assert_allclose(jaxarm.inverse_kinematics(ARM, 50, 40, 0.886701, 1), problem.goal,
                               atol=1e-12)


def test_death_trap_leaves_room_beside_its_block():
    """Its block begins 1 cm beyond the first link's reach (30 cm). With the block at x = 30
    the link's tip touched the corner (30, 0) whenever the link passed horizontal, as every
    degree-6 motion free at the samples on a grid of 8.1 million did (by hand,
    benchmarks/RESULTS.md), so none could be certified free."""
    trap = jaxarm.load_scenario("death-trap")
    x = [[-104.0, -144.0, 480.0]]  # from a grid of a6 (benchmarks/RESULTS.md)
    np.testing.assert_allclose(dense_clearance(trap, x, 20001), 1.0, atol=1e-6)  # tip to corner
    touching = trap.replace(world=jaxarm.World(boxes=[((30.0, 0.0), (70.0, 30.0))]))
    assert 0.0 <= dense_clearance(touching, x, 20001)[0] < 1e-6


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
         "[search]\nsamples = 100", r"bad.toml: search.samples must be odd for Simpson's rule, "
                                    r"got 100$"),
        ("[arm]\nlengths = [30.0, 30.0]\n[start]\npose = {x = 50.0, y = 0.0}\n"
         "[goal]\njoints = [1, 0]", r"start.pose: a pose \(x, y, phi\) needs an arm of 3 or more "
                                   r"links, got arm.lengths with 2; give the joints"),
        ("[arm]\nlengths = [30.0, 30.0, 20.0, 10.0]\n[start]\npose = {x = 50.0, y = 0.0, "
         "near = [0, 1]}\n[goal]\njoints = [1, 0, 0, 0]",
         r"start.pose.near must have 4 values, got 2"),
        (MINIMAL + f"[search]\ndegree = {MAX_DEGREE + 1}",
         rf"search.degree must be <= {MAX_DEGREE}, got {MAX_DEGREE + 1}"),
        (MINIMAL + "[search]\ninit_low = 1.0\ninit_high = -1.0",
         r"search.init_low must be < search.init_high, got 1.0 and -1.0$"),
        (MINIMAL + "[search]\ninit_high = 1e20", r"search.init_high must be within \+-10000"),
        (MINIMAL + "[search]\ncertify_tol = 1e-300",
         r"search.certify_tol must be 0 or at least 1.18e-38 cm in magnitude"),
        (MINIMAL + "[search]\ncapacities = [1000000000, 0, 0]",
         r"search.capacities\[0\] must be <= 65536, got 1000000000"),
        (MINIMAL + "[search]\ncapacities = 4", r"search.capacities must be 3 slot counts"),
        ("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [1.5, 0.5, 0.5]\n[goal]\n"
         "joints = [0, 1.5, 0]\n[[obstacles]]\ntype = 'circle'\ncenter = [100, 100]\nradius = 1\n"
         "[[obstacles]]\ntype = 'box'\nmin = [25, -5]\nmax = [35, 5]",
         r"goal posture .* collides: link 1 overlaps obstacles\[1\] by"),
        (MINIMAL.replace("[30.0]", "[1e300]"), r"arm.lengths\[0\] must be within \+-100000 cm"),
        (MINIMAL + "[[obstacles]]\ntype = 'circle'\ncenter = [0, 1e6]\nradius = 1",
         r"obstacles\[0\].center\[1\] must be within \+-100000 cm, got 1000000.0"),
        (MINIMAL + "[[obstacles]]\ntype = 'circle'\ncenter = [0, 50]\nradius = 1e-300",
         r"obstacles\[0\].radius must be 0 or at least 1.18e-38 cm"),
        (MINIMAL + "[[obstacles]]\ntype = 'box'\nmin = [-1e39, 50]\nmax = [0, 60]",
         r"obstacles\[0\].min\[0\] must be within \+-100000 cm"),
        (MINIMAL.replace("[arm]", "[arm]\njoint_limits = [[-1e39, 1]]"),
         r"joint_limits\[0\]\[0\] must be within \+-3.40282e\+38"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'circle'\ncenter = [50, 50]\nradius = -1",
         r"obstacles\[0\] radius must be > 0, got -1.0"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         + "[[obstacles]]\ntype = 'circle'\ncenter = [50, 50]\nradius = 1\n" * 3
         + "[[obstacles]]\ntype = 'circle'\ncenter = [50, 50]\nradius = 0",
         r"bad.toml: obstacles\[3\] radius must be > 0, got 0.0"),
        ("units = 'mm, deg'\n[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]",
         r"units must be 'cm, rad' \(lengths in cm, angles in rad\), got 'mm, deg'"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'polygon'\nvertices = [[0, 50], [10, 60], [0, 60], [10, 50]]",
         r"obstacles\[0\] is not convex"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'box'\nmin = [0, 50]", r"obstacles\[0\] \(box\) is missing 'max'"),
        ("[arm]\nlengths = [30.0]\n[goal]\njoints = [1]", r"\[start\] must be a table"),
        ("[arm]\nlengths = [30.0]\n[start]\njoints = [0]\n[goal]\njoints = [1]\n"
         "[[obstacles]]\ntype = 'circle'\ncenter = [50, 50, 1, 2]\nradius = 1",
         r"obstacles\[0\].center must have 2 values, got 4"),
        ("[arm]\nlengths = [30.0, 30.0]\n[start]\njoints = [0, 0, 0]\n[goal]\njoints = [1, 0]",
         r"start has 3 joint angles but arm.lengths \[30.0, 30.0\] has 2 links"),
        ("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [1e30, 2.0, -0.6]\n"
         "[goal]\njoints = [1, 0, 0]", r"start\[0\] must be an angle in \[-100, 100\] rad"),
        ("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [0.3, 1.2, -1.5]\n"
         "pose = { x = 50.0, y = -10.0, phi = 0.0 }\n[goal]\njoints = [1, 0, 0]",
         r"start.joints \[0.3, 1.2, -1.5\] and start.pose .* disagree"),
        ("[arm]\nlengths = [30.0]\nmasses = [1, 2]\n[start]\njoints = [0]\n[goal]\njoints = [1]",
         r"bad.toml: arm.masses must have one value per link \(1\), got 2"),
        ("[arm]\nlengths = [30.0]\njoint_limits = [[0.5, 2]]\n[start]\njoints = [0]\n"
         "[goal]\njoints = [1]", r"start joint 1 is 0.0 rad, outside joint_limits\[0\]"),
        ("[arm]\nlengths = [30.0]\ngravity = -1\n[start]\njoints = [0]\n[goal]\njoints = [1]",
         r"arm.gravity must be >= 0"),
        (MINIMAL + "[[obstacles]]\ntype = 'segment'\npoints = [[0, 50], [0, 50]]",
         r"bad.toml: obstacles\[0\] needs two distinct points"),
        (MINIMAL + "[[obstacles]]\ntype = 'segment'\nvertices = [[0, 50], [1, 50]]",
         r"unknown key in obstacles\[0\]: 'vertices'"),
        (MINIMAL + "[[obstacles]]\ntype = 'wall'", r"obstacles\[0\].type must be circle, box, "
         r"polygon, segment or map, got 'wall'"),
    ],
)
def test_malformed_scenarios_name_the_file_and_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(jaxarm.ScenarioError, match=message):
        jaxarm.load_scenario(path)


def test_unknown_scenario_lists_the_shipped_ones():
    with pytest.raises(ValueError,
                       match=r"unknown scenario 'paper-case-9'; shipped .*paper-case-1"):
        jaxarm.load_scenario("paper-case-9")


def test_a_posture_given_both_ways_must_agree(tmp_path):
    joints = jaxarm.inverse_kinematics(ARM, 50.0, -10.0, 0.2, -1)
    path = tmp_path / "both.toml"
    path.write_text(f"[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = {joints.tolist()}\n"
                    "pose = { x = 50.0, y = -10.0, phi = 0.2, elbow = -1 }\n"
                    "[goal]\njoints = [0.3, 1.2, -1.5]\n")
    assert jaxarm.load_scenario(path).start == tuple(joints)
    path.write_text(path.read_text().replace("elbow = -1", "elbow = 1"))
    with pytest.raises(jaxarm.ScenarioError, match="disagree: .* elbow -1"):
        jaxarm.load_scenario(path)


def test_every_problem_written_as_a_scenario_loads_back_equal(tmp_path):
    problems = [jaxarm.load_scenario(name) for name in jaxarm.available_scenarios()]
    problems.append(jaxarm.Problem(
        arm=jaxarm.Arm((25.0, 20.0, 15.0, 10.0), masses=[2.0, 1.5, 1.0, 0.5], gravity=0.0),
        joint_limits=[(-1.0, 2.0), (-3.0, 3.0), (0.0, 1.0), (-0.5, 1.5)],
        start=[0.1, 0.2, 0.3, 0.4 + 1e-9],
        goal=[1.0, -0.5, 0.25, 1 / 3], degree=7, n_samples=51, collision="sampled",
        init_low=[-1.5, -2, -3, -4, -5, -6, -7, -8], init_high=9.25, name="mine",
        description="built in code", capacities=(4, 4, 8), margin=0.25, certify_tol=0.005,
        certify_budget=300,
        world=jaxarm.World(circles=[(40.0, 30.0, 3.3)], boxes=[((-40.0, 20.0), (-30.0, 25.0))],
                           polygons=[[(-10.0, 50.0), (-20.0, 60.0), (-5.0, 70.0)]],
                           segments=[((10.0, 40.0), (20.5, 41.0))])))
    for problem in problems:
        path = jaxarm.save_scenario(problem, tmp_path / f"{problem.name}.toml")
        assert jaxarm.load_scenario(path) == problem, problem.name
        assert path.read_text() == scenario_files.to_toml(problem)
    with pytest.raises(ValueError, match=r"path must end in .toml, got '.*x.txt'"):
        jaxarm.save_scenario(problems[0], tmp_path / "x.txt")


def test_a_scenario_file_that_is_not_utf8_names_the_file(tmp_path):
    path = tmp_path / "latin.toml"
    path.write_bytes(MINIMAL.replace("[arm]", "description = 'caf\xe9'\n[arm]").encode("latin-1"))
    with pytest.raises(jaxarm.ScenarioError, match=r"latin.toml: not UTF-8 text"):
        jaxarm.load_scenario(path)


def test_saved_scenarios_write_arrays_on_one_line_and_any_text(tmp_path):
    problem = jaxarm.load_scenario("paper-case-1").replace(
        name="café", description="ünïcode \"quoted\" \\ and a tab\t",
        joint_limits=[(-3.0, 3.0)] * 3)
    folder = tmp_path / "ordner-ß"
    folder.mkdir()
    path = jaxarm.save_scenario(problem, folder / "é.toml")
    text = path.read_text(encoding="utf-8")
    assert "lengths = [30.0, 30.0, 20.0]\n" in text and "capacities = [8, 0, 4]\n" in text
    assert "joint_limits = [[-3.0, 3.0], [-3.0, 3.0], [-3.0, 3.0]]\n" in text
    assert "center = [46.0, 4.0]\n" in text and "[\n" not in text
    assert jaxarm.load_scenario(path) == problem


def test_a_pose_of_a_longer_arm_is_solved_near_its_posture(tmp_path):
    posture = np.array([1.2, 0.4, 0.3, -0.2, -0.2])  # the goal, given as a pose and a near
    absolute = np.cumsum(posture)
    x, y = float(20 * np.cos(absolute).sum()), float(20 * np.sin(absolute).sum())
    path = tmp_path / "five.toml"
    path.write_text("[arm]\nlengths = [20.0, 20.0, 20.0, 20.0, 20.0]\n"
                    "[start]\npose = { x = 60.0, y = -20.0, phi = -0.3 }\n"
                    f"[goal]\npose = {{ x = {x!r}, y = {y!r}, phi = 1.5, "
                    "near = [1.25, 0.35, 0.3, -0.15, -0.25] }\n")
    problem = jaxarm.load_scenario(path)
    for joints, (x, y, phi) in ((problem.start, (60.0, -20.0, -0.3)), (problem.goal, (x, y, 1.5))):
        end = np.asarray(jaxarm.joint_positions(problem.arm.lengths, np.float32(joints)))[-1]
        np.testing.assert_allclose(end, [x, y], atol=1e-4)
        assert np.sum(joints) == pytest.approx(phi, abs=1e-6)
    assert np.abs(np.subtract(problem.goal, posture)).max() < 0.1  # that one, of many
