"""``reproduce-paper`` (``jaxarm.paper.report``): every table of the report."""

import _thread
import contextlib
import gc
import re
import signal
import subprocess
import sys
import threading
import time
import types

import jax
import numpy as np
import pytest

import jaxarm
from jaxarm import cli
from jaxarm.paper import published, report


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
def test_cli_reproduce_paper_writes_a_report_with_every_table(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "reproduce-paper", "--out", str(tmp_path), "--restarts", "8",
                           "--suite", "paper-case-2,open-space", "--suite-restarts", "4",
                           "--degrees", "6")
    assert code == 0 and "report written" in out
    stages = [line for line in out.splitlines() if re.match(r"\[\d/5, ", line)]
    assert [line[:4] for line in stages] == ["[1/5", "[2/5", "[3/5", "[4/5", "[5/5"]
    report = (tmp_path / "report.md").read_text()
    for heading in ("Table 2", "Escape probability", "Table 3", "Tables 4 and 5", "Table 6",
                    "shipped suite", "reconstructed", "Constraint rules compared",
                    "| death-trap | A:epsilon |", "feasible set of case II", "free share",
                    "Case II's optimum in seconds", "| all four | ", "| certified |",
                    "proves free for every r: A ", "`jaxarm.certify`: ",
                    "| A, B and C pooled | our median | paper's median | Mann-Whitney p |",
                    "| 3 | +0.0007, +0.0079, +0.0339 |"):
        assert heading in report
    for image in ("case1_escape_rates.png", "case1_motion.png", "suite_escape_rates.png",
                  "case2_feasible_slices.png", "death-trap_rule_curves.png",
                  "case2_profiles.png", "case1_evolving_gains.png"):
        assert f"]({image})" in report and (tmp_path / image).stat().st_size > 5000
    assert len((tmp_path / "case1_study.csv").read_text().splitlines()) == 1 + 6 * 8
    assert_tables_render(report)


def assert_tables_render(markdown: str) -> None:
    """Every Markdown table has a header, a rule of as many cells, rows of as many cells, and
    ends at a blank line (a figure or text inside a table would end it early)."""
    lines = markdown.splitlines()
    index = 0
    while index < len(lines):
        if not lines[index].startswith("|"):
            index += 1
            continue
        cells = lines[index].count("|")
        assert re.fullmatch(r"\|(---\|)+", lines[index + 1]), lines[index:index + 2]
        assert lines[index + 1].count("|") == cells, lines[index:index + 2]
        index += 2
        while index < len(lines) and lines[index].startswith("|"):
            assert lines[index].count("|") == cells, lines[index]
            index += 1
        assert index == len(lines) or lines[index] == "", lines[index]


def test_the_report_lists_each_published_set_once_and_names_its_columns(tmp_path, case1,
                                                                        case2):
    class Method:  # the case-1 study's answers the reconstruction section reads
        n_restarts = 7

        def escape_interval(self):
            return 0.1, 0.9

        def escape_rate(self):
            return 0.5

    case1_study = types.SimpleNamespace(methods=[Method()], method=lambda label: Method())
    part = report._Report(tmp_path)
    report._reconstruction_section(part, case1, case2, case1_study)
    report._tables_4_5(part, case2)
    text = "\n".join(part.lines)
    for published_set in published.CASE_2_TABLE_4 + published.CASE_2_TABLE_5:
        assert text.count(report._vector(published_set.a6)) == 1, published_set.source
    assert text.count(report._vector(published.CASE_2_TABLE_6[0][1])) == 1  # the others: once
    assert_tables_render(text)
    row = dict(problem="paper-case-2", collision="sampled", degree=7, n_free=6,
               escape_death=0.5, escape_feasibility=1.0, best_pso=0.19, best_refined=0.2,
               median_pso=0.18, median_refined=0.19, pso_seconds=1.0, refine_seconds=2.0)
    header, _, line = report.degree_refine_table([row])
    assert header.startswith("| case | degree | free coefficients | ")
    assert header.count("escape, ") == 2 and header.count("sampled check") == 2
    assert line.startswith("| paper-case-2 | 7 | 6 | ")


def test_stage_lines_are_numbered_and_timed():
    lines = []
    stage = report._stages(lines.append, time.perf_counter() - 61.4, total=2)
    stage("first")
    stage("second")
    assert re.fullmatch(r"\[1/2, 6\d s\] first", lines[0])
    assert lines[1].startswith("[2/2, ") and lines[1].endswith(" s] second")
    with pytest.raises(StopIteration):  # more stages than announced is a bug, not a line
        stage("third")


def test_the_rules_section_adds_evosax_rows_only_where_it_is_installed(monkeypatch):
    from jaxarm.optim import evosax_adapter

    monkeypatch.setattr(evosax_adapter, "available", lambda: False)
    methods, note = report.rule_methods()
    assert methods == report.RULES and "pip install 'jaxarm[bench]'" in note
    monkeypatch.setattr(evosax_adapter, "available", lambda: True)
    methods, note = report.rule_methods()
    assert methods == report.RULES + report.EVOSAX_RULES and "CMA-ES" in note
    assert all(m.startswith(evosax_adapter.PREFIX) for m in report.EVOSAX_RULES)


def test_certified_escapes_counts_only_the_restarts_that_ended_free_per_outcome():
    """The report's *certified* cells: per outcome, the best paths ``certify`` proves free out
    of those flagged free; Table 2's 17 published paths are free on the refitted case 1 and
    a6 = 0 (the obstacle-free optimum) is blocked."""
    case1 = jaxarm.load_scenario("paper-case-1")
    table_2 = published.a6_array(published.CASE_1)
    blocked = np.zeros((1, 3))

    def outcome(x, feasible):
        return types.SimpleNamespace(best_x=x, feasible=np.asarray(feasible, bool))

    outcomes = [outcome(np.concatenate([blocked, table_2]), [True] * 18),
                outcome(blocked, [False]),
                outcome(np.concatenate([blocked, table_2[:1]]), [False, True])]
    assert report._certified_escapes(case1, outcomes) == [(17, 18), (0, 0), (1, 1)]


def test_the_suite_table_searches_under_the_certified_check_and_names_it(tmp_path):
    """Every escape column says the certified check counted it, no column re-certifies what it
    already proved, and the figure's title says seeds, preset and check. The free share is
    measured at the arm's shared capacities: the same share as at the scene's own."""
    part = report._Report(tmp_path)
    figures = []
    saved = part.figure
    part.figure = lambda figure, *args: (figures.append(figure), saved(figure, *args))
    problems = report._suite_problems(["two-circles", "paper-case-2"])
    assert all(p.collision == "certified" for p in problems)
    report._suite(part, problems, 3, 3, False)
    text = "\n".join(part.lines)
    assert_tables_render(text)
    header = next(line for line in part.lines if line.startswith("| scenario"))
    escape_columns = [c for c in header.split("|") if "escape" in c]
    assert len(escape_columns) == 2 and all("certified check" in c for c in escape_columns)
    assert "certified free" not in header
    shared = jaxarm.share_capacities(problems)
    assert shared[1].capacities != problems[1].capacities  # case 2 padded to two circles
    for problem in problems:
        row = next(line for line in part.lines if line.startswith(f"| {problem.name} "))
        share = jaxarm.feasible_fraction(problem)  # at the scene's own capacities
        assert 0 < share.fraction < 1 and f"| {share.fraction:.2%} [" in row
    [figure] = figures
    title = figure.axes[0].get_title()
    assert "preset A" in title and "3 seeds" in title and "certified check" in title
    legend = [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    assert all("certified check" in label for label in legend)


@pytest.mark.parametrize("quick, suite, degrees, expected", [
    (True, None, None, ["case 1", "cases II", "constraint rules"]),
    (True, ["open-space"], None, ["case 1", "cases II", "constraint rules", "shipped suite: 1 "]),
    (True, None, (6,), ["case 1", "cases II", "beyond the paper: degree 6 ", "constraint rules"]),
    (False, None, None, ["case 1", "cases II", "beyond the paper: degree 6, 7, 8 ",
                         "constraint rules", "shipped suite: 13 "]),
])
def test_the_quick_report_leaves_out_the_suite_and_the_degrees_unless_named(
        monkeypatch, tmp_path, quick, suite, degrees, expected):
    """``--quick`` (``make demo``) runs the paper's sections and the rules; each left-out
    section is named at the top of the report, with the flag that adds it."""
    titles = []

    def no_run(sections, out, *args):  # the plan only: no section runs
        titles.extend(section.title for section in sections)
        return []

    monkeypatch.setattr(report, "_run_sections", no_run)
    path = report.reproduce_paper(tmp_path, quick=quick, suite=suite, degrees=degrees,
                                  log=lambda text: None)
    assert len(titles) == len(expected)
    assert all(title.startswith(start) for title, start in zip(titles, expected))
    text = path.read_text()
    left_out = [flag for flag, kept in (("`--suite`", suite or not quick),
                                        ("`--degrees`", degrees or not quick)) if not kept]
    assert ("**Not in this run:**" in text) == bool(left_out)
    assert all(flag in text for flag in left_out)
    assert ("100 seeds" in titles[0]) == quick and ("500 seeds" in titles[0]) == (not quick)


@pytest.mark.parametrize("arguments, message", [
    (dict(quick=True, suite_restarts=10), "suite_restarts=10 needs a suite"),
    (dict(degrees=[]), "degrees must be a non-empty list of path degrees, got []"),
    (dict(quick=True, degrees=6), "degrees must be a non-empty list of path degrees, got 6"),
    (dict(quick=True, degrees=(6, 8, 6)), "degrees must not repeat a degree, got [6, 8, 6]"),
    (dict(quick=True, suite=["open-space", "open-space"]),
     "suite must not repeat a scenario, got ['open-space', 'open-space']"),
])
def test_report_sizes_that_would_be_ignored_are_errors(tmp_path, arguments, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        report.reproduce_paper(tmp_path / "out", log=lambda text: None, **arguments)
    assert not (tmp_path / "out").exists()  # checked before anything is written


def _section(title, text, long=False, wait=None):
    def fill(part):
        if wait is not None:
            assert wait.wait(10)
        part.add(text)
    return report._Section(title, fill, long)


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_sections_come_back_in_their_order_and_long_ones_start_first(tmp_path, workers):
    lines = []
    sections = [_section("a", "first"), _section("b", "second", long=True), _section("c", "third")]
    parts = report._run_sections(sections, tmp_path, workers, lines.append, time.perf_counter())
    assert [part.lines for part in parts] == [["first"], ["second"], ["third"]]
    started = [line.split("] ")[1] for line in lines if re.match(r"\[\d/3, ", line)]
    assert started[0] == ("a" if workers == 1 else "b") and sorted(started) == ["a", "b", "c"]
    assert sum(line.endswith(("] done: a", "] done: b", "] done: c")) for line in lines) == (
        0 if workers == 1 else 3)


def test_a_failing_section_raises_without_waiting_for_the_others(tmp_path):
    release = threading.Event()  # the other section waits until the error has come through

    def broken(part):
        raise ValueError("suite must be a non-empty list")

    sections = [_section("slow", "x", wait=release), report._Section("broken", broken)]
    try:
        with pytest.raises(ValueError, match="non-empty list"):
            report._run_sections(sections, tmp_path, 2, lambda text: None, 0.0)
    finally:
        release.set()


@contextlib.contextmanager
def collection_paused():
    """A simulated Ctrl-C that reaches the main thread as ``KeyboardInterrupt``.

    No garbage collection while it is pending: raised inside a collection's callback (jax
    registers one), ``KeyboardInterrupt`` is swallowed as unraisable (seen when the report CLI
    test had run first in the same process). And Python's own SIGINT handler: with any other
    (a test worker's or a library's), ``_thread.interrupt_main`` raises nothing (both tests
    failed so in one run of the whole suite)."""
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        signal.signal(signal.SIGINT, handler)


def test_ctrl_c_while_sections_run_starts_no_other_section(tmp_path):
    """``KeyboardInterrupt`` in the main thread (Ctrl-C in a notebook): the threads finish the
    sections they are in and start no other (they used to run the rest in the background)."""
    release, ran = threading.Event(), []

    def interrupting(part):
        _thread.interrupt_main()  # raised in the main thread, inside _run_sections' wait
        assert release.wait(10)

    sections = [report._Section("interrupting", interrupting, long=True),
                _section("slow", "x", long=True, wait=release),
                *(report._Section(name, lambda part, name=name: ran.append(name))
                  for name in ("c", "d"))]
    try:
        with collection_paused(), pytest.raises(KeyboardInterrupt):
            report._run_sections(sections, tmp_path, 2, lambda text: None, 0.0)
    finally:
        release.set()
    deadline = time.monotonic() + 10
    while report.sections_running() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not report.sections_running() and ran == []


def test_a_section_still_running_after_ctrl_c_is_seen_running(tmp_path):
    """``Thread.is_alive`` says False for a running thread whose ``join`` Ctrl-C interrupted
    (CPython 3.11); ``sections_running`` must not, or the CLI's exit tears the XLA
    runtime down under the section (``cli._leave``)."""
    release = threading.Event()

    def interrupting(part):
        time.sleep(0.3)  # the main thread is waiting in Thread.join by then
        _thread.interrupt_main()
        assert release.wait(10)

    sections = [report._Section("interrupting", interrupting, long=True),
                _section("quick", "x")]
    try:
        with collection_paused(), pytest.raises(KeyboardInterrupt):
            report._run_sections(sections, tmp_path, 2, lambda text: None, 0.0)
        assert report.sections_running()
    finally:
        release.set()
    deadline = time.monotonic() + 10
    while report.sections_running() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not report.sections_running()


def test_workers_default_to_the_cores_and_must_be_1_across_processes(monkeypatch):
    assert 1 <= report._section_workers(None) <= 5
    assert report._section_workers(3) == 3
    with pytest.raises(ValueError, match="workers must be"):
        report._section_workers(0)
    monkeypatch.setattr(jax, "process_count", lambda: 2)
    assert report._section_workers(None) == 1
    with pytest.raises(ValueError, match="workers must be 1 with 2 processes"):
        report._section_workers(2)


STOPPED_MIDWAY = """
import sys, threading, time
import jax, jax.numpy as jnp
from jaxarm import cli
from jaxarm.paper import report

def inside_xla(part):  # a section still inside an XLA program
    x = jnp.ones((300, 300))
    steps = jax.jit(lambda x: jax.lax.fori_loop(0, 10**6, lambda i, a: jnp.tanh(a @ x), x))
    steps(x).block_until_ready()

sections = [report._Section(name, inside_xla) for name in "ab"]
threading.Thread(target=report._run_sections, args=(sections, None, 2, print, 0.0),
                 daemon=True).start()
time.sleep(1.0)
sys.exit(cli._leave(130))
"""


def test_the_cli_stopped_midway_exits_with_its_code_while_sections_still_run():
    """Ctrl-C or an error while report sections run: a plain exit tore the XLA runtime down
    under them and the process aborted (code 134)."""
    done = subprocess.run([sys.executable, "-c", STOPPED_MIDWAY], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 130, done.stderr[-500:]
    assert "FATAL" not in done.stderr
