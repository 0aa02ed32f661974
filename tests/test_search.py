"""``jaxarm.solve`` and its ``Result``: arguments, fields, escape rates against the paper,
refinement, higher degrees, more links."""

import json

import numpy as np
import pytest
from sizes import SMALL

import jaxarm
from jaxarm import search
from jaxarm.choices import DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS
from jaxarm.optim import pso
from jaxarm.optim.methods import parse_method
from jaxarm.paper import published
from jaxarm.study import wilson_interval
from jaxarm.testing import oracle_separation


def test_init_particles_seed_the_swarm(case2):
    known = published.CASE_2_TABLE_3[0]  # paper Table 6's third initial particle
    result = jaxarm.solve(case2, "A", n_restarts=3, init_particles=[known.a6], **SMALL)
    assert np.all(result.restarts.escape_iter == 0)
    assert np.all(result.restarts.best_fitness >= known.fitness)
    assert np.all(result.restarts.history[:, 0] >= known.fitness)
    with pytest.raises(ValueError, match=r"init_particles must have shape \(n_given <= 8, 3\)"):
        jaxarm.solve(case2, init_particles=np.zeros((2, 4)), **SMALL)


def test_result_fields_are_consistent(case2):
    result = jaxarm.solve(case2, "A", n_restarts=5, seed=1, **SMALL)
    assert result.best_x.shape == (3,) and result.history.shape == (13,)
    assert result.restarts.best_x.shape == (5, 3) and result.restarts.history.shape == (5, 13)
    best = int(np.argmax(result.restarts.best_fitness))
    assert result.best_fitness == result.restarts.best_fitness[best]
    assert result.feasible == (result.best_fitness > 0)
    # history is the global best's fitness: non-decreasing under the death penalty
    assert np.all(np.diff(result.restarts.history, axis=1) >= 0)
    escaped = result.restarts.escape_iter >= 0
    assert np.all(result.restarts.history[escaped, -1] > 0)
    assert (result.method, result.constraint, result.collision) == ("A", "death", "sampled")
    assert "fitness" in result.summary()
    # what escapes more often is suggested only when nothing escaped
    assert ("HINT" in result.summary()) == (not result.feasible)
    restarts = result.restarts
    colliding = restarts._replace(best_violation=np.full_like(restarts.best_violation, 0.25),
                                  escape_iter=np.full_like(restarts.escape_iter, -1),
                                  best_fitness=np.zeros_like(restarts.best_fitness))
    hint = result._replace(restarts=colliding).summary()
    assert "none of 5 restart(s) of A under death rules (degree 6)" in hint
    assert "not free, violation 0.25 (cm deep at its deepest sample" in hint


def test_a_path_free_only_at_the_samples_names_where_certify_finds_it_colliding():
    """Under the sampled check, a best path free at the samples that collides between them
    gets ``certify``'s witness, which the summary prints, checked against shapely."""
    import shapely

    from jaxarm.testing import link_segments_at, shapely_obstacles

    problem = jaxarm.load_scenario("paper-case-1", collision="sampled")
    grazing = np.float32([55.03985, -58.297947, 0.61486983])  # free at the 101 samples
    result = jaxarm.solve(problem, "A", n_restarts=1, seed=0, init_particles=grazing[None],
                          **SMALL)
    assert result.feasible and not result.certified
    r, link, obstacle, distance, name = result.witness
    assert name == problem.world.obstacle_name(obstacle) and distance < 0
    segment = link_segments_at(problem, result.best_x[None].astype(np.float64),
                               np.array([[r]]))[0, 0, link]
    (centre, radius), = [shapely_obstacles(problem.world)[0][obstacle]]
    oracle = shapely.distance(shapely.linestrings(segment.reshape(2, 2)), centre) - radius
    assert oracle < 0 and abs(oracle - distance) < 1e-3
    warning = next(line for line in result.summary().splitlines() if line.startswith("WARNING"))
    assert f"between them, link {link + 1} is {-distance:.3g} cm inside {name}" in warning


def test_the_default_search_is_the_documented_portfolio_and_says_so(case2):
    result = jaxarm.solve(case2, **SMALL)
    ring, preset = DEFAULT_METHODS
    n = DEFAULT_RESTARTS
    assert (result.method, result.constraint, result.n_restarts, result.degree) == (
        f"{ring} x {n} + {preset} x {n}", DEFAULT_CONSTRAINT, 2 * n, case2.degree)
    assert f"{2 * n} restart(s), degree 6" in result.summary()
    # restarts 0 .. n - 1 are the first method's, n .. 2n - 1 the second's
    first = jaxarm.solve(case2, ring, n_restarts=n, constraint=DEFAULT_CONSTRAINT, **SMALL)
    np.testing.assert_array_equal(result.restarts.best_x[:n], first.restarts.best_x)
    both = jaxarm.solve(case2, preset, n_restarts=2 * n, constraint=DEFAULT_CONSTRAINT, **SMALL)
    np.testing.assert_array_equal(result.restarts.best_x[n:], both.restarts.best_x[n:])
    assert result.config == parse_method(DEFAULT_METHODS[result.best_restart // n]).config
    # a named method is that method, one swarm, its own rule: the paper's settings
    paper = jaxarm.solve(case2, "A", **SMALL)
    assert (paper.method, paper.constraint, paper.n_restarts) == ("A", "death", 1)
    # the default method under another rule, and with more restarts
    other = jaxarm.solve(case2, constraint="death", n_restarts=3, **SMALL)
    assert (other.method, other.constraint, other.n_restarts) == (
        f"{ring} x 3 + {preset} x 3", "death", 6)
    # a record written before the degree was kept still reads
    record = result.to_dict()
    del record["degree"]
    assert jaxarm.Result.from_dict(record).degree is None


@pytest.mark.slow
def test_the_default_search_finds_a_certified_path_on_death_trap():
    """Where preset A with the death penalty never escapes (benchmarks/default_bench.py runs
    every scene and ten seeds)."""
    result = jaxarm.solve(jaxarm.load_scenario("death-trap"))
    assert result.certified and result.collision == "certified"


def test_certified_search_returns_certified_paths(case2):
    # The sizes of the printed-answer test below: one search program (the rule is data).
    certified = case2.replace(collision="certified")
    result = jaxarm.solve(certified, "A", n_restarts=2, constraint="feasibility")
    assert result.feasible and result.certified and result.collision == "certified"
    assert bool(jaxarm.certify(certified, result.best_x).free)
    assert "not certified" not in result.summary()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(constraint="soft"), r"constraint must be one of .* got 'soft'"),
        (dict(n_particles=1), r"n_particles must be >= 2, got 1"),
        (dict(n_restarts=2.5), r"n_restarts must be an integer, got 2.5"),
        (dict(seed=-1), r"seed must be an integer in \[0, 2\*\*31\), got -1"),
        (dict(method="A:feasibility", constraint="epsilon"),
         r"method 'A:feasibility' names constraint 'feasibility' but constraint='epsilon'"),
        (dict(method="A:"), r"constraint must be one of .* got ''"),
        (dict(method="A", n_particles=10**9),
         r"1 restart\(s\) x 1000000000 particles is 1e\+09 at once, more than 4194304"),
        (dict(method="A", n_restarts=10**6), r"1000000 restart\(s\) x 20 particles is 2e\+07"),
        (dict(method="A", n_iters=10**8), r"x 100000001 iterations \(\+1\) is 1e\+08 at once"),
    ],
)
def test_bad_solve_arguments(case2, kwargs, message):
    with pytest.raises(ValueError, match=message):
        jaxarm.solve(case2, **kwargs)


def test_a_method_may_name_its_rule_as_studies_do(case2):
    """``solve(p, "A:feasibility")`` is ``solve(p, "A", constraint="feasibility")``, restart for
    restart, and restart i of ``escape_study(p, ["A:feasibility"])``."""
    sizes = dict(n_particles=6, n_iters=8, n_restarts=3, seed=2)
    named = jaxarm.solve(case2, "A:feasibility", **sizes)
    keyword = jaxarm.solve(case2, "A", constraint="feasibility", **sizes)
    both = jaxarm.solve(case2, "A:feasibility", constraint="feasibility", **sizes)
    for other in (keyword, both):
        np.testing.assert_array_equal(named.restarts.best_x, other.restarts.best_x)
    assert (named.method, named.constraint) == ("A", "feasibility")
    study = jaxarm.escape_study(case2, ["A:feasibility"], n_restarts=3, n_particles=6,
                                n_iters=8, seed=2)
    np.testing.assert_array_equal(study.method("A:feasibility").outcome.best_x,
                                  named.restarts.best_x)


def test_feasible_results_are_collision_free_by_shapely(case2):
    result = jaxarm.solve(case2, "A", n_restarts=6, constraint="feasibility", **SMALL)
    feasible = result.restarts.best_violation == 0
    assert feasible.any()
    r = np.linspace(0.0, 1.0, case2.n_samples)
    theta = jaxarm.joint_path(case2, result.restarts.best_x[feasible], r)
    positions = np.asarray(jaxarm.joint_positions(case2.arm.lengths, theta), dtype=np.float64)
    _, hit = oracle_separation(case2.world, positions[..., :-1, :].reshape(-1, 2),
                               positions[..., 1:, :].reshape(-1, 2))
    assert not hit.any()


def _escape_rate(problem, method, constraint, n_restarts=200):
    result = jaxarm.solve(problem, method, n_restarts=n_restarts, constraint=constraint, seed=0)
    return float(np.mean(result.restarts.escape_iter >= 0))


def paper_interval(method: str) -> tuple[float, float]:
    """95 % interval of the paper's Table 2 escapes (3 of 7 runs for every preset)."""
    return wilson_interval(published.CASE_1_ESCAPES[method], published.CASE_1_RUNS)


def test_case_1_death_penalty_escape_is_consistent_with_the_papers_3_of_7_for_a(case1):
    rate = _escape_rate(case1, "A", "death")
    low, high = paper_interval("A")
    assert low <= rate <= high, rate


@pytest.mark.parametrize("fixture", ["case1", "case2", "case3"])
def test_feasibility_rules_escape_on_every_paper_case(fixture, request):
    # On case 1 they did not while the rules compared the depth of a collision alone (82 %
    # over 200 seeds; benchmarks/RESULTS.md). Since its five circles that block the better
    # paths, case 1 escapes in 99.2 % of reproduce-paper's 500 seeds (sampled check;
    # RESULTS.md, The paper's report), 197 of these 200.
    assert _escape_rate(request.getfixturevalue(fixture), "A", "feasibility") >= 0.97


@pytest.mark.slow
@pytest.mark.parametrize("method", ["B", "C"])
def test_case_1_death_penalty_escape_is_consistent_with_the_papers_3_of_7(case1, method):
    rate = _escape_rate(case1, method, "death")
    low, high = paper_interval(method)
    assert low <= rate <= high, rate


def test_solve_with_refine_is_never_worse(case2):
    plain = jaxarm.solve(case2, "B", n_restarts=6, seed=2, **SMALL)
    refined = jaxarm.solve(case2, "B", n_restarts=6, seed=2, refine="all", **SMALL)
    assert refined.pso_best_fitness == plain.best_fitness
    assert refined.best_fitness >= plain.best_fitness
    assert np.all(refined.restarts.best_fitness >= plain.restarts.best_fitness)
    assert np.any(refined.restarts.best_fitness > plain.restarts.best_fitness)  # it polished
    assert not bool(jaxarm.collides(case2, refined.best_x))
    with pytest.raises(ValueError, match="refine must be False, True or 'all'"):
        jaxarm.solve(case2, refine="yes")


@pytest.mark.slow
def test_degree_8_on_case_1_warm_started_is_at_least_as_good_as_degree_6(case1):
    # Cold, degree 8 rarely escapes on case 1 (4 % of 100 restarts, benchmarks/RESULTS.md);
    # warm-started from the degree-6 optimum it can only do better.
    settings_ = dict(n_restarts=20, constraint="feasibility", seed=0)
    six = jaxarm.solve(case1, "A", **settings_)
    assert six.feasible
    eight_problem = case1.replace(degree=8)
    warm = jaxarm.solve(eight_problem, "A", init_particles=[jaxarm.raise_degree(six.best_x, 3, 8)],
                        **settings_)
    assert warm.feasible and warm.best_x.shape == (9,)
    assert warm.best_fitness >= six.best_fitness * (1 - 1e-6)
    # The higher-degree path still meets the boundary conditions.
    ends = np.asarray(jaxarm.joint_path(eight_problem, warm.best_x, np.array([0.0, 1.0])))
    np.testing.assert_allclose(ends, [case1.start, case1.goal], atol=1e-4)


@pytest.mark.slow
def test_five_link_scenario_solves_and_is_free_by_shapely():
    problem = jaxarm.load_scenario("five-link-detour")
    result = jaxarm.solve(problem, "A", n_restarts=8, constraint="feasibility", seed=0)
    assert result.feasible and result.best_x.shape == (5,)
    r = np.linspace(0.0, 1.0, problem.n_samples)
    positions = np.asarray(jaxarm.joint_positions(problem.arm.lengths,
                                                  jaxarm.joint_path(problem, result.best_x, r)),
                           dtype=np.float64)
    _, hit = oracle_separation(problem.world, positions[:, :-1].reshape(-1, 2),
                               positions[:, 1:].reshape(-1, 2))
    assert not hit.any()


def test_result_nests_the_restarts_and_round_trips_through_json(case2):
    result = jaxarm.solve(case2, "C", n_restarts=5, seed=2, constraint="feasibility", **SMALL)
    outcome = result.restarts
    assert isinstance(outcome, jaxarm.RestartOutcome)
    assert result.best_restart == outcome.best_restart()
    np.testing.assert_array_equal(result.best_x, outcome.best_x[result.best_restart])
    assert result.feasible == bool(outcome.best_violation[result.best_restart] == 0)
    text = result.to_json()  # strict JSON: NaN written as null
    assert "NaN" not in text and json.loads(text) == result.to_dict()
    loaded = jaxarm.Result.from_json(text)
    for name in outcome._fields:
        np.testing.assert_array_equal(getattr(loaded.restarts, name), getattr(outcome, name))
    assert loaded._replace(restarts=outcome) == result._replace(restarts=outcome)
    assert loaded.config == pso.PRESETS["C"]


@pytest.mark.parametrize("collision", ["sampled", "certified"])
def test_a_printed_answer_pasted_back_is_the_same_path(case2, collision):
    """``summary()`` prints a6 with enough digits to give back the same float32 values, so the
    printed optimum (on the obstacle's edge) keeps its fitness when pasted back."""
    problem = case2.replace(collision=collision)
    result = jaxarm.solve(problem, "A", n_restarts=2, seed=0)
    line = next(line for line in result.summary().splitlines() if line.startswith("best a"))
    pasted = json.loads(line.split(maxsplit=2)[2])
    np.testing.assert_array_equal(np.asarray(pasted, np.float32), result.best_x)
    assert result.feasible
    assert float(jaxarm.fitness(problem, pasted)) == result.best_fitness


def test_the_summary_labels_the_coefficients_as_the_paper_does(case2):
    result = jaxarm.solve(case2, "A", n_restarts=1, **SMALL)
    assert "\nbest a6  [" in result.summary()  # the paper's a6: one per joint
    assert [search.coefficient_label(d) for d in (6, 8)] == ["a6", "a6..a8"]


def _failed(degree: int, constraint: str) -> jaxarm.Result:
    """A result whose one restart found nothing free (made up: no search runs)."""
    from jaxarm.optim.restarts import RestartOutcome

    n_free = 3 * (degree - 5)
    outcome = RestartOutcome(np.zeros((1, n_free), np.float32), np.zeros(1, np.float32),
                             np.full(1, 2.5, np.float32), np.full(1, -1, np.int32),
                             np.full((1, n_free), np.nan, np.float32), np.zeros((1, 3)))
    return jaxarm.Result(outcome, 0, False, 0.0, "A", jaxarm.PRESETS["A"], constraint,
                         "certified", degree, 0, 1.0)


def test_a_hint_names_the_violation_apart_from_the_witness_depth():
    """The hint's number is the violation (the deepest sample's depth, plus any joint's
    excess over its limits, in rad), not how deep the path collides between samples: its
    deepest contact (``Result.witness``) says that, in the scenario's names."""
    failed = _failed(6, "death")._replace(witness=(0.25, 1, 0, -0.866, "boxes[0]"))
    hint = failed.summary(obstacle_names={"boxes[0]": "table"})
    assert ("not free, violation 2.5 (cm deep at its deepest sample, plus rad outside a "
            "joint's limits); its deepest contact: link 2 is 0.866 cm inside table at "
            "r = 0.25") in hint
    assert "collides by" not in _failed(6, "death").summary()


def test_a_hint_suggests_a_higher_degree_in_the_words_of_the_interface():
    from jaxarm.choices import MAX_DEGREE

    python, command_line = _failed(10, "death").summary(), _failed(10, "death").summary(True)
    assert "problem.replace(degree=12)" in python and "n_restarts=N" in python
    assert 'method "A:feasibility"' in python and "--" not in python
    assert "--degree 12" in command_line and "--restarts N" in command_line
    assert "--method A:feasibility" in command_line  # works whichever way the rule was named
    assert "problem.replace" not in command_line and "n_restarts" not in command_line
    assert "not free, violation 2.5 (cm deep" in python
    # feasibility rules already used: not suggested; at the highest degree: no degree
    at_most = _failed(MAX_DEGREE, "feasibility").summary(True)
    assert "try more restarts (--restarts N); the best path" in at_most
