"""Escape studies (``jaxarm.study``): Wilson intervals, reproducibility, records, sweeps."""

import json
import logging

import jax
import numpy as np
import pytest
from sizes import SMALL

import jaxarm
from jaxarm import stats, study
from jaxarm._compile.padding import equal_chunk_length


def test_study_is_reproducible_and_chunking_does_not_matter(case2):
    one = study.escape_study(case2, ["A", "B:feasibility"], n_restarts=10, chunk_size=10, **SMALL)
    chunked = study.escape_study(case2, ["A", "B:feasibility"], n_restarts=10, chunk_size=4,
                                 **SMALL)
    for a, b in zip(one.methods, chunked.methods):
        np.testing.assert_array_equal(a.outcome.escape_iter, b.outcome.escape_iter)
        np.testing.assert_array_equal(a.outcome.best_x, b.outcome.best_x)
    # seed i of a study is restart i of solve with the same seed
    result = jaxarm.solve(case2, "A", n_restarts=10, **SMALL)
    np.testing.assert_array_equal(one.method("A").outcome.best_x, result.restarts.best_x)


@pytest.mark.parametrize("n, limit, length", [(10, 4, 4), (1000, 500, 500), (1001, 500, 334),
                                               (7, 100, 7), (12, 1, 1), (999, 1000, 999)])
def test_chunk_length_splits_the_seeds_into_the_fewest_near_equal_chunks(n, limit, length):
    assert equal_chunk_length(n, limit) == length


def test_compare_gives_the_difference_its_newcombe_interval_and_fishers_p(case2):
    result = study.escape_study(case2, ["A", "A:feasibility", "C"], n_restarts=12, **SMALL)
    a, b = result.method("A:feasibility"), result.method("A")
    comparison = result.compare("A:feasibility", "A")
    counts = (int(a.escaped.sum()), 12, int(b.escaped.sum()), 12)
    assert comparison.difference == pytest.approx(a.escape_rate() - b.escape_rate())
    assert comparison.interval == stats.newcombe_interval(*counts)
    assert comparison.p_value == stats.fisher_exact(*counts)
    # paired by seed: the seeds one escaped and the other did not, counted from the CSV's rows
    rows = result.records()
    escaped = {(r["method"], r["restart"]): r["escaped"] for r in rows}
    only_a = sum(escaped[("A:feasibility", i)] and not escaped[("A", i)] for i in range(12))
    only_b = sum(escaped[("A", i)] and not escaped[("A:feasibility", i)] for i in range(12))
    assert only_a + only_b > 0  # seeds where the two disagree, for the test to count
    assert (comparison.only_a, comparison.only_b) == (only_a, only_b)
    assert comparison.mcnemar_p == stats.mcnemar_exact(only_a, only_b)
    assert [(c.a, c.b) for c in result.comparisons()] == [
        ("A:feasibility", "A"), ("C", "A"), ("C", "A:feasibility")]
    table = result.table(pairwise=True)
    assert f"| A:feasibility - A | {comparison.difference_text()} |" in table
    assert f"| {only_a} / {only_b} | {comparison.mcnemar_p:.3g} |" in table
    assert table.count("\n| C - ") == 2
    assert "comparison" not in result.table()
    assert len(json.loads(result.to_json())["comparisons"]) == 3


def test_compare_pairs_the_seeds_by_restart_not_by_row(case2):
    """A method whose rows come in another order (its restart ids with them) is paired seed by
    seed all the same; one that shares no seed has no McNemar p."""
    result = study.escape_study(case2, ["A", "A:feasibility"], n_restarts=12, **SMALL)
    first = result.method("A:feasibility")
    order = np.random.default_rng(3).permutation(12)
    shuffled = first._replace(restart_ids=first.restart_ids[order],
                              outcome=jax.tree.map(lambda a: np.asarray(a)[order],
                                                   first.outcome))
    reordered = result._replace(methods=(result.methods[0], shuffled))
    expected = result.compare("A:feasibility", "A")
    assert not np.array_equal(shuffled.escaped, first.escaped)  # the rows did move
    assert reordered.compare("A:feasibility", "A") == expected
    elsewhere = shuffled._replace(restart_ids=shuffled.restart_ids + 100)
    unpaired = result._replace(methods=(result.methods[0], elsewhere))
    comparison = unpaired.compare("A:feasibility", "A")
    assert (comparison.only_a, comparison.only_b) == (0, 0) and np.isnan(comparison.mcnemar_p)
    assert comparison.p_value == expected.p_value  # Fisher's needs no pairing


class RecordingBar:
    """Stands in for the tqdm bar: records what the study shows."""

    def __init__(self):
        self.events = []

    def set_description(self, text):
        self.events.append(("label", text))

    def set_postfix_str(self, text):
        self.events.append(("postfix", text))

    def update(self, n):
        self.events.append(("update", n))

    def close(self):
        self.events.append(("close",))


def test_progress_moves_per_chunk_and_says_when_it_compiles(case2, monkeypatch):
    bar = RecordingBar()
    monkeypatch.setattr(study, "_progress_bar", lambda *args, **kwargs: bar)
    sizes = dict(n_particles=5, n_iters=7)  # a program no other test compiles
    study.escape_study(case2, ["A", "C"], n_restarts=9, chunk_size=5, progress=True, **sizes)
    # two chunks of 5 and 4 seeds, one program: A compiles it, C (same rules) reuses it
    assert bar.events == [
        ("label", "paper-case-2 A"), ("postfix", "compiling"), ("update", 5),
        ("postfix", ""), ("update", 4),
        ("label", "paper-case-2 C"), ("postfix", ""), ("update", 5),
        ("postfix", ""), ("update", 4), ("close",)]
    bar.events.clear()
    study.escape_study(case2, ["B:feasibility"], n_restarts=9, chunk_size=5, progress=True,
                       **sizes)
    assert ("postfix", "compiling") not in bar.events  # the constraint rule is data
    bar.events.clear()
    study.escape_study(case2, ["A"], n_restarts=9, chunk_size=9, progress=True, **sizes)
    assert bar.events[1:3] == [("postfix", "compiling"), ("update", 9)]  # 9 -> 16 run: new


def test_progress_lines_count_every_methods_seeds_and_name_the_running_one(case2, caplog):
    sizes = dict(n_particles=5, n_iters=7)  # the program of the test above
    with caplog.at_level(logging.INFO, logger="jaxarm.study"):
        study.escape_study(case2, ["A", "C"], n_restarts=9, chunk_size=5, progress=False,
                           **sizes)
    said = [record.getMessage() for record in caplog.records]
    assert [m.split(",")[0] for m in said] == [
        f"paper-case-2: {done} of 18 seeds of 2 methods ({label})"
        for done, label in ((5, "A running"), (9, "A done"), (14, "C running"), (18, "C done"))]
    assert said[-1].endswith(", done") and said[0].endswith(" left")
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="jaxarm.study"):
        study.escape_study(case2, ["A"], n_restarts=9, chunk_size=5, progress=False, **sizes)
    assert [record.getMessage().split(",")[0] for record in caplog.records] == [
        "paper-case-2 A: 5 of 9 seeds", "paper-case-2 A: 9 of 9 seeds"]


def test_study_summaries_tables_and_records(case2):
    result = study.escape_study(case2, ["A", "C"], n_restarts=6, constraint="feasibility", **SMALL)
    assert [m.variant.label for m in result.methods] == ["A:feasibility", "C:feasibility"]
    summary = result.method("A:feasibility").summary()
    assert summary["escaped"] == int(np.sum(result.method("A:feasibility").outcome.escape_iter >= 0))
    curve = result.method("A:feasibility").escape_curve()
    assert curve.shape == (13,) and np.all(np.diff(curve) >= 0)
    assert curve[-1] == pytest.approx(summary["escape_rate"])
    table = result.table()
    assert table.count("\n") == 3 and "A:feasibility" in table
    assert f"escape rate, {result.collision} check" in table.splitlines()[0]
    quartiles = dict(summary, escape_iter_median=25.5, escape_iter_q1=21.5, escape_iter_q3=30.25)
    with pytest.MonkeyPatch.context() as patch:  # as the summary has them, not rounded
        patch.setattr(type(result.methods[0]), "summary", lambda self: quartiles)
        assert "| 25.5 [21.5, 30.25] |" in result.table().splitlines()[2]
    assert json.loads(result.to_json())["methods"][1]["method"] == "C:feasibility"
    records = result.records()
    assert len(records) == 12 and records[0]["restart"] == 0
    assert {r["collision"] for r in records} == {result.collision}
    assert result.to_csv().splitlines()[0].startswith("problem,method,constraint")
    with pytest.raises(KeyError, match="no method 'B'"):
        result.method("B")


def test_evolving_runs_are_the_escaped_seeds_table_2_pairs(case1):
    result = study.escape_study(case1, ["A", "B"], n_restarts=12, **SMALL)
    runs = [m.evolving_runs() for m in result.methods]
    for method, run in zip(result.methods, runs):
        outcome = method.outcome
        escaped = np.flatnonzero(outcome.escape_iter >= 0)
        assert len(escaped) >= 1 and run.escape_iter.tolist() == outcome.escape_iter[escaped].tolist()
        # death penalty: nothing is free before the escape, the last global best is the best
        assert np.all(run.escaping > 0)
        assert np.all(outcome.history[escaped, run.escape_iter - 1][run.escape_iter > 0] == 0)
        np.testing.assert_array_equal(run.evolved, outcome.best_fitness[escaped])
        np.testing.assert_array_equal(run.gain, run.evolved - run.escaping)
        assert np.all(run.gain >= 0)
    pooled = study.EvolvingRuns.pooled(runs)
    assert len(pooled.gain) == sum(len(r.gain) for r in runs)
    np.testing.assert_array_equal(pooled.escaping[:len(runs[0].gain)], runs[0].escaping)


def test_records_name_the_base_seed_and_each_restart(case2):
    """Restart i is seeded by (base seed, i): the columns say which is which."""
    result = study.escape_study(case2, ["A"], n_restarts=2, seed=5, **SMALL)
    records = result.records()
    assert [(r["base_seed"], r["restart"]) for r in records] == [(5, 0), (5, 1)]
    assert "seed" not in records[0]
    assert result.to_csv().splitlines()[0].startswith(
        "problem,method,constraint,collision,base_seed,restart,")
    data = json.loads(result.to_json())
    assert data["base_seed"] == 5 and "seed" not in data


def test_sweep_finds_feasible_intervals(case2):
    values = np.linspace(-60, 60, 241)
    fitness = study.sweep_coefficient(case2, [120.0, -50.0, 0.0], 2, values)
    intervals = study.feasible_intervals(values, fitness > 0)
    assert intervals and all(a <= b for a, b in intervals)
    for a, b in intervals:
        inside = (values >= a) & (values <= b)
        assert np.all(fitness[inside] > 0)
    assert study.feasible_intervals([1, 2, 3, 4], [True, False, True, True]) == [(1, 1), (3, 4)]


def test_study_rows_have_unique_labels_and_feasibility_comes_from_the_violation(case2):
    wide = jaxarm.PSOConfig(cognitive_coeff=2.0, social_coeff=2.0)
    narrow = jaxarm.PSOConfig(cognitive_coeff=0.5, social_coeff=0.5)
    named = jaxarm.Variant("mine", narrow, "feasibility")
    result = study.escape_study(case2, [wide, narrow, named, "A"], n_restarts=4, **SMALL)
    assert [m.variant.label for m in result.methods] == ["custom", "custom-2", "mine", "A"]
    assert result.method("custom-2").variant.config == narrow
    for method in result.methods:
        feasible = method.outcome.best_violation == 0
        np.testing.assert_array_equal(method.outcome.feasible, feasible)
        assert method.summary()["fitness_best"] == (
            method.outcome.best_fitness[feasible].max() if feasible.any() else None)
    assert result[0] == result.problem_name  # a Study indexes as the tuple it is
    assert result.problem_name == case2.name


@pytest.mark.parametrize(
    "methods, kwargs, message",
    [
        (["A", "A"], {}, r"methods must have unique labels, got 'A' twice"),
        (["A:soft"], {}, r"constraint must be one of .* got 'soft'"),
        ([], {}, r"methods must name at least one method"),
        (["A"], dict(seed=-1), r"seed must be an integer in \[0, 2\*\*31\), got -1"),
        (["A"], dict(n_iters=0), r"n_iters must be >= 1, got 0"),
        (["A"], dict(n_particles=2.5), r"n_particles must be an integer, got 2.5"),
        (["A"], dict(n_particles=1), r"n_particles must be >= 2, got 1"),
        ("AB", {}, r"method must be one of .* got 'AB'"),
        (["A"], dict(constraint="soft"), r"constraint must be one of .* got 'soft'"),
    ],
)
def test_bad_study_arguments_name_the_field(case2, methods, kwargs, message):
    with pytest.raises(ValueError, match=message):
        study.escape_study(case2, methods, n_restarts=2, **kwargs)


def test_every_export_writes_to_a_path_and_returns_text_without_one(tmp_path, case2):
    """One convention for ``Study``, ``Result`` and ``Trajectory``: a path (or an open file)
    writes, no path returns the text."""
    import io

    study = jaxarm.escape_study(case2, ["A", "B"], n_restarts=4, n_iters=5, n_particles=6)
    result = jaxarm.solve(case2, "A", n_restarts=2, n_iters=5, n_particles=6)
    trajectory = jaxarm.Trajectory(case2, result.best_x, 2.0)
    for name, export in [("study.csv", study.to_csv), ("study.json", study.to_json),
                         ("result.json", result.to_json), ("trajectory.csv", trajectory.to_csv),
                         ("trajectory.json", trajectory.to_json)]:
        text = export()
        assert isinstance(text, str) and text
        assert export(tmp_path / name) == tmp_path / name
        assert (tmp_path / name).read_bytes() == text.encode()
        buffer = io.StringIO()
        assert export(buffer) is buffer and buffer.getvalue() == text
    with pytest.raises(ValueError, match="does not exist"):
        study.to_csv(tmp_path / "missing" / "study.csv")


def test_the_table_shows_run_and_compile_time_apart(case2):
    study = jaxarm.escape_study(case2, ["A", "B"], n_restarts=4, n_iters=5, n_particles=6)
    header = study.table().splitlines()[0]
    assert "run (s)" in header and "compile (s)" in header
    for method in study.methods:
        assert 0.0 <= method.compile_seconds <= method.seconds
        summary = method.summary()
        assert summary["compile_seconds"] == method.compile_seconds
