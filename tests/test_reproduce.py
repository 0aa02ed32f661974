"""``reproduce-paper`` (``jaxarm.reproduce``): every table of the report."""

import re
import time

import pytest

from jaxarm import cli, reproduce


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
def test_cli_reproduce_paper_writes_a_report_with_every_table(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "reproduce-paper", "--out", str(tmp_path), "--seeds", "8",
                           "--suite", "paper-case-2,open-space", "--suite-seeds", "4",
                           "--degrees", "6")
    assert code == 0 and "report written" in out
    stages = [line for line in out.splitlines() if line.startswith("[")]
    assert [line[:4] for line in stages] == ["[1/5", "[2/5", "[3/5", "[4/5", "[5/5"]
    report = (tmp_path / "report.md").read_text()
    for heading in ("Table 2", "Escape probability", "Table 3", "Tables 4 and 5", "Table 6",
                    "shipped suite", "reconstructed", "Constraint rules compared",
                    "| death-trap | A:epsilon |", "feasible set of case II", "free share",
                    "Case II's optimum in seconds", "| all four | "):
        assert heading in report
    for image in ("case1_escape_rates.png", "case1_motion.png", "suite_escape_rates.png",
                  "case2_feasible_slices.png", "death-trap_rule_curves.png",
                  "case2_profiles.png"):
        assert f"]({image})" in report and (tmp_path / image).stat().st_size > 5000
    assert len((tmp_path / "case1_study.csv").read_text().splitlines()) == 1 + 6 * 8


def test_stage_lines_are_numbered_and_timed():
    lines = []
    stage = reproduce._stages(lines.append, time.perf_counter() - 61.4, total=2)
    stage("first")
    stage("second")
    assert re.fullmatch(r"\[1/2, 6\d s\] first", lines[0])
    assert lines[1].startswith("[2/2, ") and lines[1].endswith(" s] second")
    with pytest.raises(StopIteration):  # more stages than announced is a bug, not a line
        stage("third")


def test_the_rules_section_adds_evosax_rows_only_where_it_is_installed(monkeypatch):
    from jaxarm import evolution

    monkeypatch.setattr(evolution, "available", lambda: False)
    methods, note = reproduce.rule_methods()
    assert methods == reproduce.RULES and "pip install 'jaxarm[bench]'" in note
    monkeypatch.setattr(evolution, "available", lambda: True)
    methods, note = reproduce.rule_methods()
    assert methods == reproduce.RULES + reproduce.EVOSAX_RULES and "CMA-ES" in note
    assert all(evolution.is_strategy(m) for m in reproduce.EVOSAX_RULES)
