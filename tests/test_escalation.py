"""The anytime default (``jaxarm.escalation`` through ``solve``): stages, time limit, progress,
and a failure that says what ran, where the best path collides and what to try."""

import json
import logging
import math
import subprocess
import sys

import numpy as np
import pytest

import jaxarm
from jaxarm import escalation
from jaxarm.choices import MAX_DEGREE

TINY = dict(n_particles=4, n_iters=3)


@pytest.fixture(scope="module")
def trapped():
    """No path exists: the first link is walled in by two boxes beside the base, one each way
    round, and its goal angle lies past them. The sampled check: the stages are the same under
    either, and its search compiles faster."""
    return jaxarm.Problem(
        arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=[0.0, 0.5, 0.5], goal=[np.pi, -0.5, -0.5],
        world=jaxarm.World(boxes=[((-2.0, 4.0), (2.0, 10.0)), ((-2.0, -10.0), (2.0, -4.0))]),
        name="trapped", collision="sampled")


def test_the_plan_runs_more_restarts_then_each_higher_degree_seeded():
    plan = escalation.stage_plan(6, 8)
    assert plan[:4] == [(6, 8, False), (6, 8, False), (8, 8, True), (8, 24, True)]
    degrees = [stage.degree for stage in plan]
    assert degrees == sorted(degrees) and degrees[-1] == MAX_DEGREE
    assert [stage.degree for stage in escalation.stage_plan(23, 8)] == [23, 23, 24, 24]


def test_a_per_coefficient_init_range_reaches_the_new_powers(case2):
    low = tuple(-float(v) for v in range(1, 4))
    problem = case2.replace(init_low=low, init_high=tuple(-v for v in low))
    raised = escalation.at_degree(problem, 8)
    assert raised.degree == 8 and raised.init_low == low + low[-3:] * 2


def test_nothing_free_escalates_stage_by_stage_and_says_what_ran(trapped):
    seen = []
    result = jaxarm.solve(trapped, max_stages=3, progress=seen.append, **TINY)
    assert [stage.index for stage in seen] == [0, 1, 2] and result.stages == tuple(seen)
    assert [(s.degree, s.n_restarts, s.seeded) for s in seen] == [
        (6, 16, False), (6, 16, False), (8, 16, True)]
    assert not result.feasible and not result.certified
    assert "sampled collision check" in result.summary()
    assert result.degree in (6, 8) and result.best_x.shape == (3 * (result.degree - 5),)
    python, flags = result.summary(), result.summary(flags=True)
    assert "48 restart(s) in 3 stages" in python and "(degrees 6, 8)" in python
    assert "problem.replace(degree=10)" in python and "--degree 10" in flags
    assert "degree=8)" not in python and "--degree 8" not in flags  # never one already tried
    # where it collides: the witness, named as World names it (or as a file does)
    r, link, obstacle, distance, name = result.witness
    assert name == trapped.world.obstacle_name(obstacle) and name in python
    assert f"link {link + 1} is" in python
    assert "obstacles[1]" in result.summary(obstacle_names={name: "obstacles[1]"})


def test_stage_zero_alone_is_the_call_as_asked_and_a_record_repeats_the_stages(case2, trapped):
    from jaxarm.choices import DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS
    from jaxarm.optim.methods import parse_method
    from jaxarm.optim.restarts import run_restarts

    default = jaxarm.solve(case2, progress=False, **TINY)  # certified at stage 0
    assert len(default.stages) == 1 and default.certified
    # the fixed search as it was: 8 restarts of each default method, numbered 0-7 and 8-15
    by_hand = [run_restarts(case2, parse_method(name, DEFAULT_CONSTRAINT).config,
                            DEFAULT_CONSTRAINT, seed=0, first_restart=i * DEFAULT_RESTARTS,
                            n_restarts=DEFAULT_RESTARTS, **TINY)
               for i, name in enumerate(DEFAULT_METHODS)]
    np.testing.assert_array_equal(default.restarts.best_x,
                                  by_hand[0].concatenate(by_hand[1]).best_x)
    from jaxarm.io.runs import run_record

    first = jaxarm.solve(trapped, max_stages=2, progress=False, **TINY)
    record = run_record(trapped, None, dict(TINY, time_limit=30.0), first)
    assert record["settings"]["max_stages"] == 2 and record["settings"]["time_limit"] is None
    json.dumps(record, allow_nan=False)
    again = jaxarm.solve(trapped, progress=False, **record["settings"])
    np.testing.assert_array_equal(again.best_x, first.best_x)
    assert jaxarm.Result.from_dict(record["result"]).stages == first.stages


def test_improve_spends_the_stages_on_a_fitter_path(case2):
    quick = jaxarm.solve(case2, max_stages=3, progress=False, **TINY)
    better = jaxarm.solve(case2, max_stages=3, improve=True, progress=False, **TINY)
    assert len(quick.stages) == 1 and len(better.stages) == 3
    assert better.certified and better.best_fitness >= quick.best_fitness


def test_a_short_time_limit_stops_after_stage_zero(trapped, caplog):
    with caplog.at_level(logging.INFO, logger="jaxarm.search"):
        result = jaxarm.solve(trapped, time_limit=1e-3, **TINY)
    assert len(result.stages) == 1 and result.stages[0].time_ran_out
    assert "stage 0: degree 6, 16 restart(s)" in caplog.text
    assert "a longer time limit (time_limit=0.002)" in result.summary()


def test_seeds_fit_a_swarm_of_fewer_particles_than_the_seeds(trapped):
    result = jaxarm.solve(trapped, max_stages=3, progress=False, n_particles=2, n_iters=2)
    assert [stage.seeded for stage in result.stages] == [False, False, True]


def test_a_named_method_runs_once_unless_given_a_time_limit(trapped):
    assert len(jaxarm.solve(trapped, "A", **TINY).stages) == 1
    result = jaxarm.solve(trapped, "A", time_limit=math.inf, max_stages=2, progress=False,
                          **TINY)
    assert [stage.n_restarts for stage in result.stages] == [1, 1]


@pytest.mark.parametrize("field, value", [("time_limit", 0), ("time_limit", -1.0),
                                          ("time_limit", float("nan")), ("time_limit", "60"),
                                          ("max_stages", 0), ("improve", "yes"),
                                          ("progress", "loud")])
def test_bad_search_limits_name_the_field(case2, field, value):
    with pytest.raises(ValueError, match=field):
        jaxarm.solve(case2, **{field: value})
    with pytest.raises(ValueError, match="improve=True needs more than one stage"):
        jaxarm.solve(case2, "A", improve=True)  # a named method runs one stage


def test_a_result_at_a_higher_degree_goes_with_the_problem_at_that_degree(trapped):
    from jaxarm import plot

    result = jaxarm.solve(trapped, max_stages=3, progress=False, n_particles=2, n_iters=2)
    at = escalation.at_degree(trapped, result.degree)
    assert at.n_free == result.best_x.shape[0]
    assert plot.plot_motion(at, result.best_x) is not None


def test_the_command_line_reports_stages_and_where_the_best_path_collides(tmp_path, trapped):
    scene = tmp_path / "trapped.toml"
    jaxarm.save_scenario(trapped, scene)
    run = subprocess.run(
        [sys.executable, "-m", "jaxarm", "solve", str(scene), "--time-limit", "0.001",
         "--particles", "4", "--iters", "3", "--json", str(tmp_path / "run.json")],
        capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "jaxarm: stage 0: degree 6, 16 restart(s)" in run.stderr
    assert "--time-limit 0.002" in run.stdout and "--degree 8" in run.stdout
    assert "inside obstacles[" in run.stdout and "boxes[" not in run.stdout
    saved = jaxarm.load_run(tmp_path / "run.json")
    assert saved.settings["max_stages"] == 1 and saved.result.witness is not None
    # a best path found at a higher degree is drawn with the problem at that degree
    from benchmark_modules import load

    s_bend = load("default_bench").s_bend()  # no free path at degree 6
    jaxarm.save_scenario(s_bend, tmp_path / "s_bend.toml")
    climbed = subprocess.run(
        [sys.executable, "-m", "jaxarm", "solve", str(tmp_path / "s_bend.toml"),
         "--time-limit", "30", "--particles", "4", "--iters", "10",
         "--plot", str(tmp_path / "motion.png"), "--json", str(tmp_path / "climbed.json"),
         "--quiet"], capture_output=True, text=True, timeout=600)
    assert climbed.returncode == 0, climbed.stderr
    assert (tmp_path / "motion.png").stat().st_size > 0
    # its record repeats it from the degree searched first, not the one it climbed to
    saved = jaxarm.load_run(tmp_path / "climbed.json")
    assert saved.problem.degree == s_bend.degree < saved.result.degree
    again = jaxarm.solve(saved.problem, saved.method, **saved.settings)
    assert again.degree == saved.result.degree
    np.testing.assert_array_equal(again.best_x, saved.result.best_x)
    bad = subprocess.run([sys.executable, "-m", "jaxarm", "solve", "paper-case-2",
                          "--time-limit", "0"], capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--time-limit" in bad.stderr


def test_the_s_bend_has_no_free_path_at_degree_6_and_one_at_degree_7():
    """benchmarks/default_bench.py's S-bend: at degree 6 the elbow (0 at both ends) keeps one
    sign, and with either sign the free postures (shapely, on a grid over the base's range)
    leave start and goal apart; the S path of degree 7 is certified and clear by shapely."""
    shapely = pytest.importorskip("shapely")
    from scipy import ndimage

    from benchmark_modules import load
    from jaxarm.model import path
    from jaxarm.testing import dense_clearance

    bench = load("default_bench")
    problem = bench.s_bend()
    g6 = np.asarray(path.basis_values(6, np.linspace(0.0, 1.0, 101)))[:, 1]
    assert np.all(g6 <= 0.0)  # so the elbow's a6 g6(r) never changes sign
    low, high = problem.joint_limits[0]
    base = np.linspace(low, high, 161)
    elbow = np.linspace(-np.pi, np.pi, 181)
    b, e = np.meshgrid(base, elbow, indexing="ij")
    length_1, length_2 = problem.arm.lengths
    elbow_at = length_1 * np.stack([np.cos(b), np.sin(b)], -1)
    tip = elbow_at + length_2 * np.stack([np.cos(b + e), np.sin(b + e)], -1)
    links = [shapely.linestrings(np.stack([np.zeros_like(elbow_at), elbow_at], -2)),
             shapely.linestrings(np.stack([elbow_at, tip], -2))]
    free = np.ones(b.shape, bool)
    for (x, y, radius) in problem.world.circles:
        disc = shapely.Point(x, y).buffer(radius, quad_segs=64)
        for link in links:
            free &= ~shapely.intersects(link, disc)
    start, goal = (np.argmin(abs(base - problem.start[0])), 90), (np.argmin(abs(base - np.pi)), 90)
    for one_sign in (e >= 0.0, e <= 0.0):
        labels, _ = ndimage.label(free & one_sign)
        assert labels[start] and labels[goal] and labels[start] != labels[goal]
    labels, _ = ndimage.label(free)
    assert labels[start] == labels[goal]  # the grid's postures do connect them

    seven = escalation.at_degree(problem, 7)
    x = np.array([bench.S_BEND_PATH])
    assert jaxarm.certify(seven, x).free[0]
    assert dense_clearance(seven, x, 20001).min() > problem.margin


def test_a_stage_past_its_time_limit_says_so_not_a_negative_time_left():
    """A stage that ends after the limit (the limit is checked between stages) says how far
    past it, and its least violation has no unit (cm plus rad outside a joint's limits)."""
    from jaxarm.escalation import Stage

    stage = Stage(index=2, degree=8, n_restarts=16, seeded=True, escaped=0, certified=False,
                  best_fitness=0.0, best_violation=1.68, seconds=84.1, time_left=-39.2,
                  time_ran_out=True)
    assert stage.line().endswith("(least violation 1.68); 84.1 s, 39 s past the time limit")
    assert stage._replace(time_left=5.4).line().endswith("84.1 s, 5 s left")
    assert ", " not in stage._replace(time_left=float("inf")).line().split("; ")[-1]
