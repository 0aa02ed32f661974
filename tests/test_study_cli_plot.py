"""Studies (Wilson intervals, reproducibility, records), the CLI, and the figures."""

import json

import numpy as np
import pytest
from scipy import stats

import jaxarm
from jaxarm import cli, plot, study

SMALL = dict(n_particles=8, n_iters=12)


@pytest.mark.parametrize("successes, trials", [(0, 10), (3, 7), (46, 100), (500, 500), (1, 3)])
def test_wilson_interval_matches_a_reference(successes, trials):
    reference = stats.binomtest(successes, trials).proportion_ci(0.95, method="wilson")
    low, high = study.wilson_interval(successes, trials)
    assert low == pytest.approx(reference.low, abs=1e-12)
    assert high == pytest.approx(reference.high, abs=1e-12)


def test_study_is_reproducible_and_chunking_does_not_matter(case2):
    one = study.escape_study(case2, ["A", "B:feasibility"], n_seeds=10, chunk_size=10, **SMALL)
    chunked = study.escape_study(case2, ["A", "B:feasibility"], n_seeds=10, chunk_size=4,
                                 **SMALL)
    for a, b in zip(one.methods, chunked.methods):
        np.testing.assert_array_equal(a.escape_iter, b.escape_iter)
        np.testing.assert_array_equal(a.best_x, b.best_x)
    # seed i of a study is restart i of solve with the same seed
    result = jaxarm.solve(case2, "A", n_restarts=10, **SMALL)
    np.testing.assert_array_equal(one["A"].best_x, result.restart_best_x)


def test_study_summaries_tables_and_records(case2):
    result = study.escape_study(case2, ["A", "C"], n_seeds=6, constraint="feasibility", **SMALL)
    assert [m.method.label for m in result.methods] == ["A:feasibility", "C:feasibility"]
    summary = result["A:feasibility"].summary()
    assert summary["escaped"] == int(np.sum(result["A:feasibility"].escape_iter >= 0))
    curve = result["A:feasibility"].escape_curve()
    assert curve.shape == (13,) and np.all(np.diff(curve) >= 0)
    assert curve[-1] == pytest.approx(summary["escape_rate"])
    table = result.table()
    assert table.count("\n") == 3 and "A:feasibility" in table
    assert json.loads(result.to_json())["methods"][1]["method"] == "C:feasibility"
    records = result.records()
    assert len(records) == 12 and records[0]["restart"] == 0
    assert result.to_csv().splitlines()[0].startswith("problem,method,constraint")
    with pytest.raises(KeyError, match="no method 'B'"):
        result["B"]


def test_sweep_finds_feasible_intervals(case2):
    values = np.linspace(-60, 60, 241)
    fitness = study.sweep_coefficient(case2, [120.0, -50.0, 0.0], 2, values)
    intervals = study.feasible_intervals(values, fitness > 0)
    assert intervals and all(a <= b for a, b in intervals)
    for a, b in intervals:
        inside = (values >= a) & (values <= b)
        assert np.all(fitness[inside] > 0)
    assert study.feasible_intervals([1, 2, 3, 4], [True, False, True, True]) == [(1, 1), (3, 4)]


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_scenarios_lists_every_shipped_scenario(capsys):
    code, out, _ = run_cli(capsys, "scenarios")
    assert code == 0
    assert len(out.splitlines()) == len(jaxarm.available_scenarios()) >= 11


def test_cli_solve_writes_json_and_plot(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", "--particles", "8", "--iters", "12",
                           "--restarts", "2", "--json", str(tmp_path / "r.json"),
                           "--plot", str(tmp_path / "r.png"))
    assert code == 0 and "fitness" in out
    data = json.loads((tmp_path / "r.json").read_text())
    assert len(data["best_x"]) == 3 and len(data["history"]) == 13
    assert (tmp_path / "r.png").stat().st_size > 5000


def test_cli_study_writes_json_csv_and_plot(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "study", "paper-case-2", "--seeds", "4", "--methods",
                           "A,A:feasibility", "--particles", "8", "--iters", "12",
                           "--json", str(tmp_path / "s.json"), "--csv", str(tmp_path / "s.csv"),
                           "--plot", str(tmp_path / "s.png"))
    assert code == 0 and "escape rate" in out
    assert len((tmp_path / "s.csv").read_text().splitlines()) == 9
    assert len(json.loads((tmp_path / "s.json").read_text())["methods"]) == 2
    assert (tmp_path / "s.png").stat().st_size > 5000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["solve", "no-such-scenario"], "unknown scenario 'no-such-scenario'"),
        (["solve", "missing.toml"], "cannot read scenario file 'missing.toml'"),
        (["solve", "paper-case-2", "--degree", "4"], "degree must be >= 6, got 4"),
        (["study", "paper-case-2", "--methods", "A,Z"], "method must be one of"),
        (["solve", "paper-case-2", "--seed", "-3"], "seed must be an integer"),
    ],
)
def test_cli_errors_are_one_line_without_traceback(capsys, argv, message):
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_cli_reports_malformed_and_colliding_scenarios(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[arm\n")
    code, _, err = run_cli(capsys, "solve", str(bad))
    assert code == 2 and "malformed TOML" in err and err.count("\n") == 1
    colliding = tmp_path / "colliding.toml"
    colliding.write_text("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [0, 0, 0]\n"
                         "[goal]\njoints = [1, 0, 0]\n[[obstacles]]\ntype = 'circle'\n"
                         "center = [40, 0]\nradius = 3\n")
    code, _, err = run_cli(capsys, "solve", str(colliding))
    assert code == 2 and "start posture" in err and "link 2 overlaps circles[0]" in err


def test_cli_help_on_every_subcommand(capsys):
    for command in ("scenarios", "solve", "study", "reproduce-paper"):
        with pytest.raises(SystemExit) as exit_info:
            cli.main([command, "--help"])
        assert exit_info.value.code == 0
        assert "usage: jaxarm" in capsys.readouterr().out


def test_plots_produce_non_empty_pngs(tmp_path, case2):
    result = jaxarm.solve(case2, "A", n_restarts=4, **SMALL)
    escape = study.escape_study(case2, ["A", "A:feasibility"], n_seeds=4, **SMALL)
    figures = {
        "motion": plot.plot_motion(case2, result.best_x),
        "joints": plot.plot_joint_angles(case2, result.best_x),
        "convergence": plot.plot_convergence(result.restart_history, result.restart_escape_iter),
        "rates": plot.plot_escape_rates(escape),
        "curves": plot.plot_escape_curves(escape),
    }
    for name, figure in figures.items():
        path = tmp_path / f"{name}.png"
        figure.savefig(path)
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000
    gif = tmp_path / "motion.gif"
    plot.animate(case2, result.best_x, gif, n_frames=5)
    assert gif.read_bytes()[:6] == b"GIF89a"




@pytest.mark.slow
def test_cli_reproduce_paper_writes_a_report_with_every_table(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "reproduce-paper", "--out", str(tmp_path), "--seeds", "8",
                           "--suite", "paper-case-2,open-space", "--suite-seeds", "4",
                           "--degrees", "6")
    assert code == 0 and "report written" in out
    report = (tmp_path / "report.md").read_text()
    for heading in ("Table 2", "Escape probability", "Table 3", "Tables 4 and 5", "Table 6",
                    "shipped suite", "reconstructed"):
        assert heading in report
    for image in ("case1_escape_rates.png", "case1_motion.png", "suite_escape_rates.png"):
        assert f"]({image})" in report and (tmp_path / image).stat().st_size > 5000
    assert len((tmp_path / "case1_study.csv").read_text().splitlines()) == 1 + 6 * 8
