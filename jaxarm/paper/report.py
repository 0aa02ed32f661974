"""``reproduce_paper``: every experiment of the paper, and the studies beyond it, in one report.

Writes ``report.md`` with its tables and figures (PNG), plus the studies as JSON and CSV, to an
output folder. Everything is seeded: the same command gives the same numbers.
"""

from __future__ import annotations

import collections
import datetime
import math
import os
import pathlib
import platform
import sys
import threading
import time
from typing import Callable, NamedTuple

import jax
import numpy as np
from matplotlib.figure import Figure
from scipy.stats import mannwhitneyu

from jaxarm import plot, study
from jaxarm._compile.padding import SMALL_BATCH
from jaxarm._validate import positive_int
from jaxarm.checks.evaluate import certify, fitness
from jaxarm.choices import LIMIT_UNITS, MAX_DEGREE, MIN_DEGREE
from jaxarm.feasible import feasible_fraction
from jaxarm.io import scenario_files
from jaxarm.io.files import output_folder, written
from jaxarm.model.problem import share_capacities
from jaxarm.optim import evosax_adapter
from jaxarm.optim.methods import parse_method
from jaxarm.optim.refine import refine
from jaxarm.optim.restarts import N_ITERS, N_PARTICLES, run_restarts
from jaxarm.paper import published, reconstruct
from jaxarm.search import exact_text, solve
from jaxarm.stats import wilson_interval
from jaxarm.trajectory import Trajectory, min_duration


def _vector(x, digits=4) -> str:
    return "[" + ", ".join(f"{v:.{digits}f}" for v in np.asarray(x)) + "]"


class _Report:
    """Markdown lines plus the figures saved beside them."""

    def __init__(self, out: pathlib.Path):
        self.out, self.lines = out, []

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def figure(self, figure, name: str, caption: str) -> None:
        with written(self.out / name) as path:
            figure.savefig(path, dpi=110)
        self.add(f"![{caption}]({name})", "")

    def text(self, name: str, text: str) -> pathlib.Path:
        """Write ``text`` to the file ``name`` beside the report, whole (``io.files.written``)."""
        with written(self.out / name) as path:
            path.write_text(text, encoding="utf-8")
        return self.out / name

    def write(self) -> pathlib.Path:
        return self.text("report.md", "\n".join(self.lines) + "\n")


def _print(text: str) -> None:
    """``print``, clearing the progress bars (tqdm, on stderr) first and drawing them again
    below the line."""
    from tqdm import tqdm

    tqdm.write(text, file=sys.stdout)


def reproduce_paper(out_dir="results", *, quick: bool = False, n_restarts: int | None = None,
                    suite: list[str] | None = None, suite_restarts: int | None = None,
                    degrees=None, log: Callable[[str], None] = _print,
                    progress: bool | None = None, workers: int | None = None):
    """Run the paper's experiments and the studies beyond it; write ``out_dir/report.md``.

    Args:
      out_dir: output folder (created).
      quick: the demo: the paper's tables and the constraint rules at 100 seeds; the suite
        and the degree comparison only where ``suite`` or ``degrees`` names them (50 seeds
        per suite scenario, 20 restarts per degree): each of their scenes and degrees
        compiles programs of its own.
      n_restarts: seeds of the case-1 study and the rules section (default 500, or 100 when
        quick).
      suite: distinct scenario names for the suite study (default: every shipped scenario but
        those at scale, ``AT_SCALE``; none when quick).
      suite_restarts: seeds per suite scenario (default 200, or 50 when quick; given to a
        quick report without a suite, an error rather than ignored).
      degrees: a non-empty list of distinct path degrees compared in the beyond-the-paper section
        (default 6, 7 and 8; none when quick).
      log: where progress lines go (default: stdout, above any progress bars).
      progress: progress bars (default: when stderr is a terminal).
      workers: threads running the report's sections side by side (default: the cores
        this process may use, at most 5; 1 when JAX has several devices or processes, whose
        programs must start in the same order everywhere). Results do not depend on it; times
        do: one section compiles while another runs (``benchmarks/RESULTS.md``, *Decisions and
        negative results*, "Report sections side by side").
        Interrupted (Ctrl-C), the threads finish the sections they are in and start no other.

    Returns:
      The path of the report.
    """
    began = time.perf_counter()
    # Every name and size is checked before the first study: a typo fails in a second.
    n_restarts, suite, suite_restarts, degrees = _report_sizes(quick, n_restarts, suite,
                                                               suite_restarts, degrees)
    workers = _section_workers(workers)
    out = output_folder("out_dir", out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = _Report(out)
    sections = _report_sections(quick, n_restarts, suite, suite_restarts, degrees, progress)
    _introduction(report, quick, workers, suite, degrees)
    for part in _run_sections(sections, out, workers, log, began):
        report.add(*part.lines)
    report.add(f"Total time: {time.perf_counter() - began:.0f} s.")
    path = report.write()
    log(f"report written to {path} ({time.perf_counter() - began:.0f} s)")
    return path


def _report_sizes(quick: bool, n_restarts, suite, suite_restarts, degrees) -> tuple:
    """``reproduce_paper``'s sizes checked, defaults filled in and the suite's scenarios loaded:
    ``(n_restarts, suite problems, suite_restarts, degrees)``."""
    n_restarts = (positive_int("n_restarts", n_restarts) if n_restarts is not None
                  else (100 if quick else 500))
    if quick and suite is None and suite_restarts is not None:
        raise ValueError(f"suite_restarts={suite_restarts} needs a suite: a quick report runs "
                         "none unless suite (--suite) names its scenarios")
    suite_restarts = (positive_int("suite_restarts", suite_restarts) if suite_restarts is not None
                   else (50 if quick else 200))
    if suite is None:
        suite = [] if quick else _suite_problems(
            [name for name in scenario_files.available() if name not in AT_SCALE])
    else:
        suite = _suite_problems(suite)
    if degrees is None:
        degrees = () if quick else (6, 7, 8)
    elif isinstance(degrees, (str, int)) or not len(degrees):
        raise ValueError(f"degrees must be a non-empty list of path degrees, got {degrees!r}")
    degrees = [positive_int("degrees", d, minimum=MIN_DEGREE, maximum=MAX_DEGREE)
               for d in degrees]
    if len(set(degrees)) < len(degrees):
        raise ValueError(f"degrees must not repeat a degree, got {degrees}")
    return n_restarts, suite, suite_restarts, degrees


def _report_sections(quick: bool, n_restarts: int, suite: list, suite_restarts: int,
                     degrees: list, progress) -> list:
    """The report's sections (``_Section``s) after its introduction, in the report's order;
    those of an empty suite or no degrees left out."""
    chunk = _shared_chunk(n_restarts, suite_restarts if suite else None)
    # The paper's tables use the paper's check: collision-free at the 101 samples of r.
    case1, case2, case3 = (scenario_files.load_scenario(name, collision="sampled")
                           for name in ("paper-case-1", "paper-case-2", "paper-case-3"))
    # The rules section runs case 1 and death-trap as the suite runs its scenes.
    rules_problems = _suite_problems(["paper-case-1", "death-trap"])

    def case_1(part: _Report) -> None:
        methods = ["A", "B", "C", "A:feasibility", "B:feasibility", "C:feasibility"]
        case1_study = study.escape_study(case1, methods, n_restarts=n_restarts, chunk_size=chunk,
                                         progress=progress)
        part.text("case1_study.json", case1_study.to_json())
        part.text("case1_study.csv", case1_study.to_csv())
        _table_2(part, case1_study)
        _reconstruction_section(part, case1, case2, case1_study)
        _escape_section(part, case1, case1_study)

    def tables_3_to_6(part: _Report) -> None:
        _table_3(part, case2, case3)
        _tables_4_5(part, case2)
        _table_6(part, case2)

    def rules_and_case_2(part: _Report) -> None:
        _rules_section(part, rules_problems, n_restarts, chunk, progress)
        _feasible_set_section(part, case2)
        _trajectory_section(part, case2)

    sections = [
        _Section(f"case 1: escape study, {n_restarts} seeds x 6 methods", case_1),
        _Section("cases II and III (Table 3), Tables 4-6", tables_3_to_6),
        _Section(f"beyond the paper: degree {', '.join(map(str, degrees))} and PSO + refine",
                 lambda part: part.add(*_beyond_paper_section(
                     [p.replace(collision="certified") for p in (case1, case2, case3)],
                     20 if quick else 100, degrees)), long=True) if degrees else None,
        _Section(f"constraint rules compared on case 1 and death-trap, {n_restarts} seeds each",
                 rules_and_case_2),
        _Section(f"shipped suite: {len(suite)} scenarios x {suite_restarts} seeds x 2 methods",
                 lambda part: _suite(part, suite, suite_restarts, chunk, progress),
                 long=True) if suite else None,
    ]
    return [section for section in sections if section is not None]


def _introduction(report: _Report, quick: bool, workers: int, suite: list, degrees: list) -> None:
    """The report's title and the paragraphs before its sections."""
    report.add(
        "# jaxarm: reproduction of Machmudah & Parman (2013)", "",
        f"Generated {datetime.datetime.now():%Y-%m-%d %H:%M} by `jaxarm reproduce-paper"
        f"{' --quick' if quick else ''}` (jax {jax.__version__}, {jax.default_backend()}, "
        f"{platform.processor() or platform.machine()}). Swarm: 20 particles, 100 iterations, "
        "as in the paper.", "",
        "**Which check counts an escape.** jaxarm's default, the *certified* check, calls a path "
        "collision-free only when `jaxarm.certify` proves it free for every r in [0, 1]. The "
        "paper's own tables (Tables 2-6 and the case-1 escape study) use the paper's check, "
        "free at its 101 samples of r, as the paper did, and say so in their captions: most "
        "of those escapes cross an obstacle between two samples, and each table counts the "
        "ones `jaxarm.certify` proves free. The sections beyond the paper (degree, constraint "
        "rules, the suite) search under the certified check, so every escape they count is a "
        "path proved collision-free.", "",
        "**Scenarios are reconstructed.** The paper's figures of case 1's postures and of every "
        "obstacle did not survive; the shipped scenarios are fitted to its published numbers "
        "(see *How the scenarios were reconstructed* below). Fitness values of published "
        "coefficient sets do not depend on the obstacles; feasibility verdicts and escape rates "
        "do.", "",
        f"Section times include compilation; the study tables give run and compile times "
        f"apart. {_workers_sentence(workers)}", "",
    )
    left_out = ([] if suite else ["the shipped suite (`--suite`)"]) + (
        [] if degrees else ["the path degrees compared (`--degrees`)"])
    if left_out:
        report.add(f"**Not in this run:** {' and '.join(left_out)}. Each of their scenes and "
                   "degrees compiles programs of its own; `jaxarm reproduce-paper` without "
                   "`--quick` runs them, and either flag adds its section here.", "")


class _Section(NamedTuple):
    """One section of the report: a stage line, and what writes its lines and figures."""

    title: str
    fill: Callable[[_Report], None]
    long: bool = False  # started first when sections run side by side


def _section_workers(workers: int | None) -> int:
    """Threads for the sections: ``workers``, or the default (``reproduce_paper``)."""
    single = jax.process_count() == 1 and jax.device_count() == 1
    if workers is None:
        cores = getattr(os, "process_cpu_count", os.cpu_count)() or 1
        return min(cores, 5) if single else 1
    workers = positive_int("workers", workers)
    if workers > 1 and not single:
        raise ValueError(f"workers must be 1 with {jax.process_count()} processes and "
                         f"{jax.device_count()} devices (their programs must start in the same "
                         f"order everywhere), got {workers}")
    return workers


def _workers_sentence(workers: int) -> str:
    if workers == 1:
        return "The report's sections ran one after another (`--workers 1`)."
    return (f"The report's sections ran side by side on {workers} threads (`--workers`), "
            "sharing the cores, so each time is longer than that work alone; no result "
            "depends on it.")


SECTION_THREADS = "jaxarm-report-section"
# Section threads that have not returned. Not ``Thread.is_alive``: it says False for a running
# thread once Ctrl-C has interrupted a ``join`` on it (tested on CPython 3.11).
_unfinished_threads: set[threading.Thread] = set()


def sections_running() -> bool:
    """Whether a section thread of an unfinished report still runs (``_run_sections``)."""
    return bool(_unfinished_threads)


def _run_sections(sections: list, out: pathlib.Path, workers: int,
                  log: Callable[[str], None], began: float) -> list:
    """Each section filled into a ``_Report`` of its own; the reports in the sections' order.

    With ``workers`` > 1 the sections run on that many threads, the long ones first, and each
    logs when it starts and ends; the first error is raised once the main thread sees it, and
    Ctrl-C (``KeyboardInterrupt`` in the main thread) at once. Then no section starts: the
    threads finish the section they are in (they are daemons, so an exiting process does not
    wait for them). Sections must not depend on one another.
    """
    parts = [_Report(out) for _ in sections]
    log = _one_line_at_a_time(log)
    stage = _stages(log, began, total=len(sections))

    def run(index: int) -> None:
        stage(sections[index].title)
        sections[index].fill(parts[index])
        if workers > 1:
            log(f"[{time.perf_counter() - began:.0f} s] done: {sections[index].title}")

    if workers == 1:
        for index in range(len(sections)):
            run(index)
        return parts
    waiting = collections.deque(sorted(range(len(sections)), key=lambda i: not sections[i].long))
    errors, lock = [], threading.Lock()

    def worker() -> None:
        try:
            while True:
                with lock:
                    if errors or not waiting:
                        return
                    index = waiting.popleft()
                try:
                    run(index)
                except BaseException as error:  # noqa: BLE001 - raised in the main thread
                    with lock:
                        errors.append(error)
                    return
        finally:
            _unfinished_threads.discard(threading.current_thread())

    threads = [threading.Thread(target=worker, name=f"{SECTION_THREADS}-{n}", daemon=True)
               for n in range(min(workers, len(sections)))]
    try:
        for thread in threads:
            _unfinished_threads.add(thread)  # until the thread returns
            thread.start()
        for thread in threads:
            while thread.is_alive() and not errors:
                thread.join(0.1)  # in short waits, so that Ctrl-C reaches the main thread
    except BaseException:  # Ctrl-C: before, a notebook's threads went on with the rest
        with lock:
            waiting.clear()
        _unfinished_threads.difference_update(t for t in threads if t.ident is None)  # unstarted
        raise
    if errors:
        raise errors[0]
    return parts


def _one_line_at_a_time(log: Callable[[str], None]) -> Callable[[str], None]:
    """``log`` for several threads: ``print``'s text and newline are two writes."""
    lock = threading.Lock()

    def locked(text: str) -> None:
        with lock:
            log(text)

    return locked


def _stages(log: Callable[[str], None], began: float, total: int) -> Callable[[str], None]:
    """A logger that numbers the stages and says how long the run has taken so far:
    ``[2/5, 41 s] cases II and III``."""
    count = iter(range(1, total + 1))

    def stage(text: str) -> None:
        log(f"[{next(count)}/{total}, {time.perf_counter() - began:.0f} s] {text}")

    return stage


def _table_2(report: _Report, case1_study) -> None:
    report.add(
        "## Table 2: escaping and evolving, 7 runs x A, B, C on case 1", "",
        "The paper's check (free at the 101 samples) and death penalty, as in the paper. "
        "Runs 1-7 are seeds 0-6 of the study below. Each cell: *Escaping* (iteration, fitness) "
        "and the global best at escape; *Evolving* (100, fitness) and the final best; or fail.",
        "",
        "| PSO | " + " | ".join(f"Run {i + 1}" for i in range(7)) + " | escaped (paper) |",
        "|---|" + "---|" * 8,
    )
    for label in "ABC":
        method = case1_study.method(label).outcome
        cells = []
        for run in range(7):
            escape = int(method.escape_iter[run])
            if escape < 0:
                cells.append("fail")
                continue
            cells.append(
                f"Escaping ({escape}, {method.history[run, escape]:.4f}) "
                f"a6={_vector(method.escape_x[run], 2)}<br>Evolving (100, "
                f"{method.best_fitness[run]:.4f}) a6={_vector(method.best_x[run], 2)}"
            )
        escaped = int(np.sum(method.escape_iter[:7] >= 0))
        report.add(f"| {label} | " + " | ".join(cells)
                   + f" | {escaped}/7 ({published.CASE_1_ESCAPES[label]}/7) |")
    report.add("")
    _evolving_gains(report, case1_study)


def paper_evolving_runs(presets: str = "ABC") -> dict[str, study.EvolvingRuns]:
    """The paper's escaped case-1 runs (Table 2), per preset: ``{"A": study.EvolvingRuns, ...}``."""
    return {preset: study.EvolvingRuns(*(np.array(field) for field in zip(*[
        (run.escape_iter, run.escaping.fitness, run.evolved.fitness)
        for run in published.CASE_1_ESCAPED_RUNS if run.preset == preset])))
        for preset in presets}


def _evolving_gains(report: _Report, case1_study) -> None:
    """Table 2's evolving column over every seed: what escaped runs gain after the escape."""
    paper = paper_evolving_runs()
    ours = {label: case1_study.method(label).evolving_runs() for label in "ABC"}
    pooled_ours, pooled_paper = (study.EvolvingRuns.pooled(list(runs.values()))
                                 for runs in (ours, paper))
    n_seeds = case1_study.method("A").n_restarts

    def spread(gains) -> str:
        q1, median, q3 = np.percentile(gains, [25, 50, 75])
        return f"{median:+.4f} [{q1:+.4f}, {q3:+.4f}]"

    report.add(
        f"What an escaped run gains between its escape and iteration 100, over all {n_seeds} "
        "seeds of the study below (the same check and rule) against the paper's nine escaped "
        "runs. Median [quartiles]; the two-sided Mann-Whitney U test (scipy) asks whether "
        "the paper's gains could come from the same distribution as ours.", "",
        "| preset | our escaped seeds | our gain | paper's runs | paper's gains |",
        "|---|---|---|---|---|",
        *[f"| {label} | {len(ours[label].gain)} | "
          + (spread(ours[label].gain) if len(ours[label].gain) else "n/a")
          + f" | {len(paper[label].gain)} | "
          + ", ".join(f"{g:+.4f}" for g in paper[label].gain) + " |" for label in ours],
        f"| A, B and C | {len(pooled_ours.gain)} | "
        + (spread(pooled_ours.gain) if len(pooled_ours.gain) else "n/a")
        + f" | {len(pooled_paper.gain)} | {spread(pooled_paper.gain)} |", "",
    )
    if len(pooled_ours.gain):
        rows = [("gain", pooled_ours.gain, pooled_paper.gain, "+.4f")] + [
            (name, getattr(pooled_ours, field), getattr(pooled_paper, field), spec)
            for name, field, spec in [("escape iteration", "escape_iter", ".0f"),
                                      ("fitness at escape", "escaping", ".4f"),
                                      ("fitness at iteration 100", "evolved", ".4f")]]
        report.add(
            "| A, B and C pooled | our median | paper's median | Mann-Whitney p |",
            "|---|---|---|---|",
            *[f"| {name} | {np.median(a):{spec}} | {np.median(b):{spec}} | "
              f"{mannwhitneyu(a, b, alternative='two-sided').pvalue:.3f} |"
              for name, a, b, spec in rows], "",
        )
        report.figure(plot.plot_evolving_gains(ours, paper, title=(
            f"Case 1, death penalty, sampled check: gain after escape\n({n_seeds} seeds per "
            "preset; the paper's escaped runs as dots)")), "case1_evolving_gains.png",
            "Gain after escape, ours and the paper's")


def _verdict(fitness_value: float) -> str:
    return "free" if fitness_value > 0 else "collides"


def _reconstruction_section(report: _Report, case1, case2, case1_study) -> None:
    """The shipped scenarios against the published numbers they were fitted to."""
    case1_verdicts = reconstruct.label_agreement(case1, published.CASE_1)
    errors = [abs(v.fitness - v.published.fitness) / v.published.fitness for v in case1_verdicts]
    report.add(
        "## How the scenarios were reconstructed", "",
        "`jaxarm.paper.reconstruct` fitted case 1's start and goal postures to Table 2: fitness "
        "depends "
        "only on the joint displacement, so with the end-effector held at (50, -10) and (50, 40) "
        "the two end-effector orientations and elbows are the unknowns "
        f"(fitted: start phi = {_orientation(case1.start):.4f} rad, goal phi = "
        f"{_orientation(case1.goal):.4f} rad, elbow +1). Obstacles: the largest circles that "
        "keep every published feasible set clear, picked to block the most of the initial range "
        "and every published infeasible set; on case 1, further circles that keep Table 2's "
        "motions about 0.05 cm clear block every path above fitness 0.18 (the paper's best: "
        "0.1774; `benchmarks/blocking.py` proves none is free at the samples by branch and "
        "bound) and narrow the free set near the optimum; "
        "`benchmarks/reconstruct_scenarios.py` runs every step. One layout consistent with "
        "the paper's numbers, not the paper's own.", "",
        f"Case 1, Table 2's coefficient sets on the shipped scenario (worst relative fitness "
        f"error {max(errors):.1e}; C run 5's evolved set, printed with a62 = +69.649, is left "
        "out: fitness is even in each a6, so its sign cannot be checked):", "",
        "| Table 2 set | a6 | paper fitness | ours | relative error | paper | ours |",
        "|---|---|---|---|---|---|---|",
        *[f"| {v.published.source} | {_vector(v.published.a6)} | {v.published.fitness} | "
          f"{v.fitness:.4f} | {e:.1e} | {_verdict(v.published.fitness)} | {_verdict(v.fitness)} |"
          for v, e in zip(case1_verdicts, errors)],
        "", "Case 1, death-penalty escape over "
        f"{case1_study.methods[0].n_restarts} seeds against the paper's 7 runs:", "",
        "| preset | ours [95 % CI] | paper [95 % CI] |", "|---|---|---|",
    )
    for label in "ABC":
        method = case1_study.method(label)
        low, high = method.escape_interval()
        paper_low, paper_high = study.wilson_interval(published.CASE_1_ESCAPES[label],
                                                      published.CASE_1_RUNS)
        report.add(f"| {label} | {method.escape_rate():.0%} [{low:.0%}, {high:.0%}] | "
                   f"{published.CASE_1_ESCAPES[label]}/{published.CASE_1_RUNS} "
                   f"[{paper_low:.0%}, {paper_high:.0%}] |")
    verdicts = reconstruct.label_agreement(case2, published.CASE_2)
    others = [v for v in verdicts if not v.published.source.startswith(_TABLES_4_5)]
    report.add(
        "",
        "Case II, every set the paper evaluated (Tables 3-6): "
        f"{sum(v.agrees for v in verdicts)}"
        f" of {len(verdicts)} verdicts agree. Tables 4 and 5's sets are listed with theirs in "
        "their own section; the others:", "",
        "| source | a6 | paper fitness | ours | paper | ours |", "|---|---|---|---|---|---|",
        *[f"| {v.published.source} | {_vector(v.published.a6)} | {v.published.fitness:g} | "
          f"{v.fitness:.4f} | {_verdict(v.published.fitness)} | {_verdict(v.fitness)}"
          f"{_disagrees(v)} |" for v in others],
        "",
    )


_TABLES_4_5 = ("Table 4", "Table 5")  # sources of the sets ``_tables_4_5`` lists


def _disagrees(verdict) -> str:
    """A marker after our verdict where it is not the paper's."""
    return "" if verdict.agrees else " (disagrees)"


def _orientation(joints) -> float:
    """End-effector orientation (absolute angle of the last link) of a posture."""
    return float(np.angle(np.exp(1j * np.sum(joints))))


def _escape_section(report: _Report, case1, case1_study) -> None:
    n = case1_study.methods[0].n_restarts
    report.add(
        f"## Escape probability on case 1 over {n} seeds (the paper's sampled check)", "",
        "The paper's 7 runs per variant cannot separate the variants; this can. Beside the "
        "paper's death penalty, the same presets with feasibility rules (feasible beats "
        "infeasible; between colliding paths, less penetration times travelling distance "
        "beats more).", "",
        case1_study.table(), "",
        "Escapes are counted under the paper's check (free at the 101 samples). Of the "
        "restarts that escaped, those whose best path `jaxarm.certify` proves free for every r: "
        + ", ".join(f"{method.variant.label} {proved}/{escaped}" for method, (proved, escaped)
                    in zip(case1_study.methods, _certified_escapes(
                        case1, [m.outcome for m in case1_study.methods]))) + ".", "",
    )
    report.figure(plot.plot_escape_rates(case1_study), "case1_escape_rates.png",
                  "Escape rates on case 1")
    report.figure(plot.plot_escape_curves(case1_study), "case1_escape_curves.png",
                  "Fraction escaped by iteration")
    method = case1_study.method("A").outcome
    n_shown = min(60, len(method.escape_iter))  # more curves would hide one another
    report.figure(plot.plot_convergence(method.history[:n_shown], method.escape_iter[:n_shown],
                                        title=f"Case 1, preset A, death penalty, sampled "
                                              f"check\nfirst {n_shown} of "
                                              f"{len(method.escape_iter)} seeds (paper Fig. 12)"),
                  "case1_convergence.png", "Escape and evolution, preset A")
    rules = case1_study.method("A:feasibility").outcome
    x = rules.best_x[rules.best_restart()]
    proof = certify(case1, x)
    depth = -float(proof.clearance)
    between = ("certified free for every r" if bool(proof.free) else
               f"it enters an obstacle between two samples ({depth:.2g} cm deep)"
               if bool(proof.colliding) else "not proved free between the samples")
    report.add(f"Best path found on case 1 (free at the samples): a6 = {exact_text(x)}, "
               f"fitness {float(fitness(case1, x)):.4f}; `jaxarm.certify`: {between}.", "")
    report.figure(plot.plot_motion(case1, x, title="Case 1: best path (paper Fig. 11)"),
                  "case1_motion.png", "Case 1 motion")
    report.figure(plot.plot_joint_angles(case1, x, title="Case 1: joint angles (paper Fig. 7b)"),
                  "case1_joint_angles.png", "Case 1 joint angles")


def _table_3(report: _Report, case2, case3) -> None:
    report.add(
        "## Table 3: cases II and III, preset A, 100 generations", "",
        "| case | paper a6 | paper fitness | our fitness of the paper's a6 | our a6 (seed 0) | "
        "our fitness | certified |",
        "|---|---|---|---|---|---|---|",
    )
    results = {}
    paper_sets = {case2.name: published.CASE_2_TABLE_3[0][1:],
                  case3.name: published.CASE_3[0][1:]}
    for problem in (case2, case3):
        paper_x, paper_fitness = paper_sets[problem.name]
        result = results[problem.name] = solve(problem, "A", seed=0)
        report.add(
            f"| {problem.name} | {_vector(paper_x)} | {paper_fitness} | "
            f"{float(fitness(problem, paper_x)):.4f} | {exact_text(result.best_x)} | "
            f"{result.best_fitness:.4f} | {result.certified} |"
        )
    report.add("", "Our fitness beats the paper's where the reconstructed obstacle leaves room "
               "the paper's did not; *certified* says whether the path also passes the "
               "continuous check (optima hug the obstacle, so between samples they often graze "
               "it).", "")
    report.figure(plot.plot_motion(case2, results[case2.name].best_x, title="Case II: best path"),
                  "case2_motion.png", "Case II motion")


def _tables_4_5(report: _Report, case2) -> None:
    def rows(sets) -> list[str]:  # fitness 0: colliding
        return [f"| {_vector(v.published.a6)} | {v.published.fitness:g} | {v.fitness:.4f}"
                f"{_disagrees(v)} |" for v in reconstruct.label_agreement(case2, sets)]

    report.add(
        "## Tables 4 and 5: is the feasible set of a6 a box? (case II)", "",
        "| a6 | paper fitness | our fitness |", "|---|---|---|",
        *rows(published.CASE_2_TABLE_4),
        "", "Table 5's test cases:", "",
        "| a6 | paper fitness | our fitness |", "|---|---|---|",
        *rows(published.CASE_2_TABLE_5),
        "", "Sweeping a63 with a61, a62 fixed (step 0.05): the feasible intervals, against the "
        "largest feasible a63 the paper found by hand.", "",
        "| a61, a62 | feasible a63 intervals | paper's largest feasible a63 |", "|---|---|---|",
    )
    values = np.arange(-60.0, 60.0001, 0.05)
    for base, paper_max in published.CASE_2_TABLE_5_SWEEPS:
        feasible = study.sweep_coefficient(case2, base, 2, values) > 0
        intervals = study.feasible_intervals(values, feasible)
        text = ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in intervals) or "none"
        report.add(f"| {base[0]}, {base[1]} | {text} | {paper_max} |")
    report.add("", "Paper: the feasible set is not a box; each composition has its own "
               "interval. The sweep shows the same with the reconstructed obstacle.", "")


def _table_6(report: _Report, case2) -> None:
    report.add(
        "## Table 6: evolution seeded with a known feasible particle (case II, preset A)", "",
        "| initial particle (fitness) | paper after 100 generations | ours after 100 |",
        "|---|---|---|",
    )
    for given, paper_x, paper_fitness in published.CASE_2_TABLE_6:
        result = solve(case2, "A", seed=0, init_particles=[given])
        report.add(
            f"| {_vector(given)} ({float(fitness(case2, given)):.4f}) | {_vector(paper_x)} "
            f"({paper_fitness}) | {exact_text(result.best_x)} ({result.best_fitness:.4f}) |"
        )
    report.add("")


# Shipped scenes left out of the default suite: those of hundreds of obstacles, whose cost is
# measured on its own (``benchmarks/scene_scale.py``), and OMPL's kinematic chains of 5 to 20
# links with self-collision (``benchmarks/peers.py --kinematic-chain``); their searches would
# take the suite many times as long. Name them in ``suite`` to study them.
AT_SCALE = ("clutter-100", "clutter-500", "workcell-map", "kinematic-chain-5",
            "kinematic-chain-10", "kinematic-chain-20")


def _suite_problems(names) -> list:
    """Scenarios under the certified check, loaded before any study so that a bad name or file
    fails first. Each keeps its own obstacle capacities for its searches: the certified check
    computes every padded slot in its costlier tests."""
    if isinstance(names, str) or not names:
        raise ValueError(f"suite must be a non-empty list of scenario names, got {names!r}")
    if len(set(names)) < len(names):
        raise ValueError(f"suite must not repeat a scenario, got {list(names)!r}")
    return [scenario_files.load_scenario(name, collision="certified") for name in names]


def _shared_chunk(n_restarts: int, suite_restarts: int | None) -> int:
    """Seeds per compiled call in every study of the report: the greatest common divisor of the
    two study sizes when it is at least 20 (100 in full), so that the rules section's case-1
    and death-trap studies reuse the suite's programs (results do not depend on it); else
    ``escape_study``'s default. Without a suite (None), its default takes the suite's place."""
    common = math.gcd(n_restarts, study.CHUNK_SIZE if suite_restarts is None else suite_restarts)
    return common if common >= 20 else study.CHUNK_SIZE


_CERTIFIED_ESCAPE = "An escape is a path the certified check proves collision-free for every r. "


def _certified_escapes(problem, outcomes) -> list[tuple[int, int]]:
    """For each ``RestartOutcome`` (NumPy arrays over seeds): how many best paths of the
    restarts that ended free under the study's check ``certify`` proves free for every r, and
    how many such restarts there are. ``certify`` runs on blocks of its smallest batch (one
    compiled program per problem spec and batch)."""
    paths = [outcome.best_x[outcome.feasible] for outcome in outcomes]
    rows = np.concatenate(paths)
    free = np.concatenate([np.zeros(0, bool)] + [
        np.asarray(certify(problem, rows[i:i + SMALL_BATCH]).free)
        for i in range(0, len(rows), SMALL_BATCH)])
    ends = np.cumsum([len(p) for p in paths])
    return [(int(free[end - len(p):end].sum()), len(p)) for p, end in zip(paths, ends)]


def _suite(report: _Report, problems: list, n_restarts: int, chunk: int, progress) -> None:
    """The suite's table and figure: each scene searched under its own check (certified) and
    capacities; its free share measured at the arm's shared capacities (``share_capacities``:
    one compiled check per arm instead of one per distinct capacities; the padded slots are
    empty)."""
    check = "certified"  # ``_suite_problems`` loads every scene under it
    report.add(
        f"## The shipped suite: escape rates over {n_restarts} seeds (preset A, {check} "
        "check)", "",
        _CERTIFIED_ESCAPE,
        "*Free share*: the share of the init range whose paths are collision-free under the "
        f"{check} check (`jaxarm.feasible_fraction`, 10,000 uniform draws); *start*: the "
        "probability that the initial swarm of 20 already holds a free path, predicted from it "
        "(1 - (1 - p)^20) and measured (seeds escaped at iteration 0, death penalty).", "",
        f"| scenario | links | death penalty: escape, {check} check [95 % CI] | feasibility "
        f"rules: escape, {check} check [95 % CI] | best fitness | free share [95 % CI] | "
        "start: predicted / measured |",
        "|---|---|---|---|---|---|---|",
    )
    rates = []
    for problem, shared in zip(problems, share_capacities(problems)):
        result = study.escape_study(problem, ["A", "A:feasibility"], n_restarts=n_restarts,
                                    chunk_size=chunk, progress=progress)
        cells = [_rate_cell(int(m.escaped.sum()), m.n_restarts) for m in result.methods]
        best = max(float(m.outcome.best_fitness.max()) for m in result.methods)
        share = feasible_fraction(shared)
        predicted, _ = share.start_escape(20)
        report.add(f"| {problem.name} | {problem.n_joints} | " + " | ".join(cells)
                   + f" | {best:.4f} | {share.fraction:.2%} [{share.interval[0]:.2%}, "
                   f"{share.interval[1]:.2%}] | {predicted:.0%} / "
                   f"{result.methods[0].start_escape_rate():.0%} |")
        rates.append((problem.name, result))
    report.add("")
    bars = [(f"death penalty: escape, {check} check",
             [r.methods[0].escape_rate() for _, r in rates]),
            (f"feasibility rules: escape, {check} check",
             [r.methods[1].escape_rate() for _, r in rates])]
    figure = Figure(figsize=(9.0, 4.2), layout="constrained")
    ax = figure.add_subplot()
    positions = np.arange(len(rates))
    width = 0.8 / len(bars)
    for index, (label, heights) in enumerate(bars):
        ax.bar(positions + (index - (len(bars) - 1) / 2) * width, heights, width, label=label)
    ax.set_xticks(positions, [name for name, _ in rates], rotation=40, ha="right",
                  fontsize=8)
    ax.set_ylabel("share of seeds")
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title(f"The shipped suite: preset A, {n_restarts} seeds per scene, {check} check "
                 "search")
    report.figure(figure, "suite_escape_rates.png", "Escape rates on the suite")


def _rate_cell(successes: int, trials: int) -> str:
    """``successes / trials`` as a rate with its 95 % Wilson interval, for a table cell."""
    low, high = wilson_interval(successes, trials)
    return f"{successes / trials:.0%} [{low:.0%}, {high:.0%}]"


# The last row is the default search's ring: inertia falling from 1 to 0.4 instead of 0, chosen
# on death-trap among four schedules (benchmarks/RESULTS.md, *Constraint rules and topologies*).
RULES = ["A", "A:feasibility", "A:epsilon", "A:penalty", "A-ring:feasibility", "A-ring:epsilon",
         "A-global-ring:epsilon", "A-ring[inertia_end=0.4]:feasibility"]
EVOSAX_RULES = ["evosax:CMA_ES", "evosax:CMA_ES:feasibility", "evosax:DE", "evosax:DE:feasibility"]


def rule_methods() -> tuple[list, str]:
    """The rules section's methods: ``RULES``, and ``EVOSAX_RULES`` where evosax is installed;
    and a sentence saying which."""
    if evosax_adapter.available():
        return RULES + EVOSAX_RULES, (
            "The evosax rows run CMA-ES and differential evolution (evosax's defaults, "
            "population 20) in the same compiled restart loop, same seeds and budget.")
    return RULES, ("evosax is not installed here, so its CMA-ES and differential-evolution "
                   "rows are left out (`pip install 'jaxarm[bench]'` adds them).")


def _rules_section(report: _Report, problems: list, n_restarts: int, chunk: int,
                   progress) -> None:
    check = "certified"  # ``_suite_problems`` loads both scenes under it
    methods, evosax_note = rule_methods()
    curves = []
    report.add(
        "## Constraint rules compared (preset A, and evosax strategies)", "",
        f"{n_restarts} seeds per row, the {check} check. {_CERTIFIED_ESCAPE}"
        "Rules (`jaxarm.optim.constraints`): the "
        "paper's death penalty, feasibility rules, the epsilon-constrained comparison and an "
        "adaptive penalty; *ring* rows use the lbest ring topology instead of the global best, "
        "*global-ring* the global best for the first 5 % of the iterations and the ring after; "
        "`[inertia_end=0.4]` lets the inertia fall from 1 to 0.4 instead of 0. "
        "Escape rate is CEC 2006's *feasible rate*; fitness medians are over the restarts that "
        "end feasible. The last column compares each row's escape rate with the death "
        "penalty's (difference, 95 % Newcombe interval, Fisher's exact p for independent "
        "samples and McNemar's exact p on the paired seeds: the rows share their seeds). "
        f"{evosax_note}", "",
        f"| scenario | rule | escape, {check} check [95 % CI] | median escape iter | median / "
        "best fitness | vs death penalty |",
        "|---|---|---|---|---|---|",
    )
    for problem in problems:
        result = study.escape_study(problem, methods, n_restarts=n_restarts, chunk_size=chunk,
                                    progress=progress)
        for method in result.methods:
            s = method.summary()
            versus = "–"
            if method.variant.label != "A":
                c = result.compare(method.variant.label, "A")
                versus = (f"{c.difference_text()}, Fisher p = {c.p_value:.2g}, "
                          f"McNemar p = {c.mcnemar_p:.2g}")
            median = "–" if s["fitness_median"] is None else f"{s['fitness_median']:.4f}"
            best = "–" if s["fitness_best"] is None else f"{s['fitness_best']:.4f}"
            iteration = ("–" if s["escape_iter_median"] is None
                         else f"{s['escape_iter_median']:.0f}")
            report.add(f"| {problem.name} | {method.variant.label} | "
                       f"{s['escape_rate']:.1%} [{s['ci95_low']:.1%}, {s['ci95_high']:.1%}] | "
                       f"{iteration} | {median} / {best} | {versus} |")
        curves.append((problem.name, plot.plot_escape_curves(result)))
    report.add("")
    for name, figure in curves:  # after the table: a figure inside it would end it
        report.figure(figure, f"{name}_rule_curves.png",
                      f"{name}: fraction escaped by iteration, each rule")


def _feasible_set_section(report: _Report, case2) -> None:
    optimum = np.array(published.CASE_2_TABLE_3[0].a6, dtype=np.float64)
    share = feasible_fraction(case2)
    report.add(
        "## The feasible set of case II (the paper's section 11.3)", "",
        f"{share.fraction:.2%} [{share.interval[0]:.2%}, {share.interval[1]:.2%}] of case II's "
        f"init range is collision-free ({share.n_paths:,} uniform draws, sampled check), so "
        f"a swarm of 20 starts with a free path with probability "
        f"{share.start_escape(20)[0]:.0%}. The slices below pass through the paper's optimum "
        f"{exact_text(optimum)} (cross), one pair of coefficients varied at a time over the "
        "init range; grey paths collide. The free set is not a box: in these slices it is a "
        "wedge with slanted edges (and in the (a62, a63) slice a second, separate piece), and "
        "the optimum sits at the wedge's tip, on its edge.", "",
    )
    figure = Figure(figsize=(13.0, 3.9), layout="constrained")
    for k, dims in enumerate(((0, 1), (0, 2), (1, 2))):
        ax = figure.add_subplot(1, 3, k + 1)
        plot.plot_feasible_map(case2, optimum, dims=dims, resolution=101, ax=ax,
                               title=f"a6{dims[0] + 1} and a6{dims[1] + 1} (sampled check)",
                               point_label="the paper's optimum")
        ax.set_xlabel(f"a6{dims[0] + 1}")
        ax.set_ylabel(f"a6{dims[1] + 1}")
    report.figure(figure, "case2_feasible_slices.png",
                  "Case II: fitness on three slices through the optimum")


# Limits for case II's trajectory: a modest arm, per joint where the loads differ.
TRAJECTORY_LIMITS = {"max_velocity": 1.0, "max_acceleration": 2.0, "max_jerk": 10.0,
                     "max_torque": (40.0, 20.0, 5.0)}


def _trajectory_section(report: _Report, case2) -> None:
    optimum = np.array(published.CASE_2_TABLE_3[0].a6, dtype=np.float64)
    rows = []
    for name, limit in TRAJECTORY_LIMITS.items():
        duration = min_duration(case2, optimum, **{name: limit})
        rows.append(f"| {name} = {limit} {LIMIT_UNITS[name.removeprefix('max_')]} | "
                    f"{duration:.4f} |")
    duration = min_duration(case2, optimum, **TRAJECTORY_LIMITS)
    trajectory = Trajectory(case2, optimum, duration)
    ends = trajectory.torques([0.0, duration])
    report.add(
        "## Case II's optimum in seconds (eqs. 8-9)", "",
        "The paper gives the links' masses (3, 3 and 2 kg) but not the plane the arm moves in; "
        "here it is vertical (gravity 9.81 m/s^2 along -y) and the links are uniform rods. "
        f"Holding the start posture takes {_vector(ends[0], 2)} N m, the goal "
        f"{_vector(ends[1], 2)} N m. The shortest transfer time of the paper's optimum "
        f"{exact_text(optimum)} under each limit alone (`jaxarm.min_duration`), and under all "
        "of them:", "",
        "| limit | shortest T (s) |", "|---|---|", *rows,
        f"| all four | {duration:.4f} |", "",
    )
    report.figure(plot.plot_profiles(trajectory, **{k: v for k, v in TRAJECTORY_LIMITS.items()
                                                    if k != "max_jerk"}),
                  "case2_profiles.png",
                  f"Case II's optimum at T = {duration:.3f} s: limits dashed")


def compare_degrees_and_refine(problems, degrees=(6, 7, 8), n_restarts: int = 100,
                               seed: int = 0) -> list[dict]:
    """Escape rates and fitness of preset A at several degrees, before and after ``refine``.

    For each problem and degree: the death-penalty and feasibility-rule escape rates over
    ``n_restarts`` restarts, the best and median final fitness of the feasibility-rule restarts,
    the same after refining every feasible restart, and wall times (compilation included).
    """
    def restarts(problem, constraint):  # solve's restarts, without certifying its answer
        return run_restarts(problem, parse_method("A").config, constraint,
                            n_particles=N_PARTICLES, n_iters=N_ITERS, seed=seed,
                            first_restart=0, n_restarts=n_restarts)

    rows = []
    for problem in problems:
        for degree in degrees:
            higher = problem.replace(degree=degree)
            death = restarts(higher, "death")
            began = time.perf_counter()
            rules = restarts(higher, "feasibility")
            pso_seconds = time.perf_counter() - began
            feasible = rules.feasible
            began = time.perf_counter()
            # every restart, so that each degree's refine is one program whatever the number
            # of feasible restarts (an infeasible one comes back unchanged and is dropped)
            polished = refine(higher, rules.best_x)
            refine_seconds = time.perf_counter() - began
            pso_fitness = rules.best_fitness[feasible]
            refined = polished.fitness[feasible]
            rows.append({
                "problem": problem.name, "collision": problem.collision, "degree": degree,
                "n_free": higher.n_free,
                "escape_death": float(np.mean(death.escape_iter >= 0)),
                "escape_feasibility": float(np.mean(rules.escape_iter >= 0)),
                "best_pso": float(pso_fitness.max(initial=0.0)),
                "best_refined": float(np.max(refined, initial=0.0)),
                "median_pso": float(np.median(pso_fitness)) if feasible.any() else 0.0,
                "median_refined": float(np.median(refined)) if feasible.any() else 0.0,
                "pso_seconds": pso_seconds, "refine_seconds": refine_seconds,
            })
    return rows


def degree_refine_table(rows: list[dict]) -> list[str]:
    """Markdown lines for ``compare_degrees_and_refine``'s rows (of one collision check, which
    the escape columns name)."""
    check = rows[0]["collision"]
    lines = [
        f"| case | degree | free coefficients | escape, death, {check} check | escape, "
        f"feasibility, {check} check | best PSO | best PSO + refine | median PSO | median PSO "
        "+ refine | PSO time (s) | refine time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['problem']} | {r['degree']} | {r['n_free']} | {r['escape_death']:.0%} | "
            f"{r['escape_feasibility']:.0%} | {r['best_pso']:.4f} | {r['best_refined']:.4f} | "
            f"{r['median_pso']:.4f} | {r['median_refined']:.4f} | {r['pso_seconds']:.1f} | "
            f"{r['refine_seconds']:.1f} |"
        )
    return lines


def _beyond_paper_section(problems, n_restarts: int, degrees=(6, 7, 8)) -> list[str]:
    rows = compare_degrees_and_refine(share_capacities(problems), degrees, n_restarts=n_restarts)
    return [
        f"## Beyond the paper: degree {', '.join(map(str, degrees))} and PSO + refine "
        f"({n_restarts} restarts, preset A)",
        "",
        f"Searches under the {problems[0].collision} check. Escape rates under both rules; "
        "fitness over the feasibility-rule restarts that ended "
        "feasible, before and after `jaxarm.refine` (optax Adam on distance plus a clearance "
        "barrier, steps accepted only when collision-free and no less fit). Times include "
        "compilation. The cases run at shared obstacle capacities "
        "(`jaxarm.share_capacities`).", "",
        *degree_refine_table(rows), "",
    ]
