"""Escape-probability studies over many seeds, and coefficient sweeps (paper Tables 2, 4-5).

A study runs every seed of a method as one restart of one compiled search (in chunks, with a
progress bar on a terminal). Seed i of a study is restart i of ``solve(..., seed=seed)``, so
every row can be re-run alone, bit for bit, whatever the chunking.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import logging
import math
import pathlib
import sys
import time
from typing import NamedTuple, Sequence

import numpy as np

from jaxarm._compile.padding import equal_chunk_length
from jaxarm._compile.timing import compile_time
from jaxarm._validate import check_search, positive_int
from jaxarm.checks.evaluate import fitness
from jaxarm.io.checkpoints import SavedRestarts, StudyCheckpoint, study_identity
from jaxarm.io.files import text_writer, write_or_return
from jaxarm.model.problem import Problem, check_problem
from jaxarm.optim.methods import Variant, parse_methods, swarm_size
from jaxarm.optim.restarts import (
    N_ITERS,
    N_PARTICLES,
    RestartOutcome,
    is_compiled,
    run_restarts,
)
from jaxarm.stats import (Comparison, fisher_exact, mcnemar_exact, newcombe_interval,
                          wilson_interval)


class EvolvingRuns(NamedTuple):
    """The paper's Table 2 pairs for escaped runs: the global best's fitness at the escape
    (its *escaping* entry, ``escaping``) and at the last iteration (its *evolving* entry,
    ``evolved``)."""

    escape_iter: np.ndarray  # shape=(n_runs,), int: the first iteration with a free particle
    escaping: np.ndarray  # shape=(n_runs,): the global best's fitness at that iteration
    evolved: np.ndarray  # shape=(n_runs,): the global best's fitness at the last iteration

    @property
    def gain(self) -> np.ndarray:
        """Fitness gained between the escape and the last iteration, shape (n_runs,)."""
        return self.evolved - self.escaping

    @staticmethod
    def pooled(runs: Sequence[EvolvingRuns]) -> EvolvingRuns:
        """Several methods' runs as one set."""
        return EvolvingRuns(*(np.concatenate(field) for field in zip(*runs)))


class MethodStudy(NamedTuple):
    """Per-restart outcomes of one variant over a study's seeds, and their summaries."""

    variant: Variant
    restart_ids: np.ndarray  # shape=(n_restarts,), the restart index of each row
    outcome: RestartOutcome  # NumPy arrays with leading axis n_restarts
    seconds: float  # wall time, compilation included
    compile_seconds: float  # of which tracing, lowering and compiling programs (or loading
    #   them from the persistent compilation cache): ``jaxarm._compile.timing``

    @property
    def n_restarts(self) -> int:
        return int(self.restart_ids.shape[0])

    @property
    def escaped(self) -> np.ndarray:
        """Shape (n_restarts,), bool: the swarm found a feasible path at some iteration."""
        return self.outcome.escape_iter >= 0

    def escape_rate(self) -> float:
        return float(self.escaped.mean())

    def escape_interval(self) -> tuple[float, float]:
        return wilson_interval(int(self.escaped.sum()), self.n_restarts)

    def start_escape_rate(self) -> float:
        """Share of seeds whose initial swarm already holds a feasible path (iteration 0);
        ``FeasibleFraction.start_escape`` predicts it from the feasible share of the range."""
        return float(np.mean(self.outcome.escape_iter == 0))

    def escape_curve(self) -> np.ndarray:
        """Fraction of seeds escaped by iteration k, shape (n_iters + 1,)."""
        n_iters = self.outcome.history.shape[1] - 1
        iters = np.where(self.escaped, self.outcome.escape_iter, n_iters + 1)
        return (iters[:, None] <= np.arange(n_iters + 1)).mean(axis=0)

    def evolving_runs(self) -> EvolvingRuns:
        """The escaped seeds' Table 2 pairs, in seed order (from the global best's history)."""
        runs = np.flatnonzero(self.escaped)
        escape = self.outcome.escape_iter[runs]
        history = np.asarray(self.outcome.history, np.float64)
        return EvolvingRuns(escape, history[runs, escape], history[runs, -1])

    def summary(self) -> dict:
        """Escape rate, 95 % Wilson interval, escape-iteration quartiles, fitness quantiles."""
        low, high = self.escape_interval()
        escaped_iters = self.outcome.escape_iter[self.escaped]
        feasible_fitness = self.outcome.best_fitness[self.outcome.feasible]
        quartiles = (np.percentile(escaped_iters, [25, 50, 75]).tolist()
                     if escaped_iters.size else [None] * 3)
        fitness_q = (np.percentile(feasible_fitness, [50, 100]).tolist()
                     if feasible_fitness.size else [None, None])
        return {
            "method": self.variant.label,
            "velocity_rule": self.variant.config.velocity_rule,
            "constraint": self.variant.constraint,
            "n_restarts": self.n_restarts,
            "escaped": int(self.escaped.sum()),
            "escape_rate": self.escape_rate(),
            "ci95_low": low,
            "ci95_high": high,
            "start_escape_rate": self.start_escape_rate(),
            "escape_iter_q1": quartiles[0],
            "escape_iter_median": quartiles[1],
            "escape_iter_q3": quartiles[2],
            "fitness_median": fitness_q[0],
            "fitness_best": fitness_q[1],
            "seconds": self.seconds,
            "compile_seconds": self.compile_seconds,
        }


class Study(NamedTuple):
    """An escape-probability study: one ``MethodStudy`` per method, same seeds for all."""

    problem_name: str
    collision: str
    n_particles: int
    n_iters: int
    seed: int  # the base seed: restart i is seeded by (seed, i), ``base_seed`` in JSON and CSV
    methods: tuple[MethodStudy, ...]

    def method(self, label: str) -> MethodStudy:
        """The ``MethodStudy`` of the method labelled ``label`` ("A", "A:feasibility", ...)."""
        for method in self.methods:
            if method.variant.label == label:
                return method
        raise KeyError(f"no method {label!r} in this study; have "
                       f"{[m.variant.label for m in self.methods]}")

    def compare(self, a: str, b: str) -> Comparison:
        """Escape rate of method ``a`` minus that of ``b``: the difference, its 95 % Newcombe
        interval and the two-sided Fisher exact p-value (the two counted as independent
        samples), and McNemar's exact p-value on the seeds they share (paired: the seeds one
        method escaped and the other did not, ``only_a`` and ``only_b``)."""
        first, second = self.method(a), self.method(b)
        counts = (int(first.escaped.sum()), first.n_restarts, int(second.escaped.sum()),
                  second.n_restarts)
        _, in_first, in_second = np.intersect1d(first.restart_ids, second.restart_ids,
                                                return_indices=True)
        escaped_a, escaped_b = first.escaped[in_first], second.escaped[in_second]
        only_a, only_b = int(np.sum(escaped_a & ~escaped_b)), int(np.sum(escaped_b & ~escaped_a))
        return Comparison(a=a, b=b, difference=first.escape_rate() - second.escape_rate(),
                          interval=newcombe_interval(*counts), p_value=fisher_exact(*counts),
                          only_a=only_a, only_b=only_b,
                          mcnemar_p=mcnemar_exact(only_a, only_b) if len(in_first) else math.nan)

    def comparisons(self) -> list[Comparison]:
        """Every pair of methods, each later one against each earlier one."""
        labels = [m.variant.label for m in self.methods]
        return [self.compare(b, a) for i, a in enumerate(labels) for b in labels[i + 1:]]

    def table(self, pairwise: bool = False) -> str:
        """Markdown table: escape rate with 95 % CI (its header names the collision check),
        escape-iteration quartiles, fitness, and each method's time spent running apart from
        the time spent compiling (the first method to use a program compiles it; the others
        reuse it); with ``pairwise``, a second table of every pair's difference in escape rate
        (``compare``)."""
        lines = [
            f"| method | constraint | escaped | escape rate, {self.collision} check [95 % CI] "
            "| escape iter median [q1, q3] | best fitness median / max | run (s) | "
            "compile (s) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        fmt = lambda v, spec: "–" if v is None else format(v, spec)  # noqa: E731
        for method in self.methods:
            s = method.summary()
            lines.append(
                f"| {s['method']} | {s['constraint']} | {s['escaped']}/{s['n_restarts']} | "
                f"{s['escape_rate']:.1%} [{s['ci95_low']:.1%}, {s['ci95_high']:.1%}] | "
                f"{fmt(s['escape_iter_median'], 'g')} [{fmt(s['escape_iter_q1'], 'g')}, "
                f"{fmt(s['escape_iter_q3'], 'g')}] | {fmt(s['fitness_median'], '.4f')} / "
                f"{fmt(s['fitness_best'], '.4f')} | "
                f"{s['seconds'] - s['compile_seconds']:.1f} | {s['compile_seconds']:.1f} |"
            )
        if pairwise and len(self.methods) > 1:
            lines += ["", "| comparison | difference in escape rate [95 % CI] | Fisher p | "
                      "seeds only a / only b escaped | McNemar p |", "|---|---|---|---|---|"]
            lines += [f"| {c.a} - {c.b} | {c.difference_text()} | {c.p_value:.3g} | "
                      f"{c.only_a} / {c.only_b} | {c.mcnemar_p:.3g} |"
                      for c in self.comparisons()]
        return "\n".join(lines)

    def to_json(self, path_or_file=None) -> str | pathlib.Path:
        """Summaries, settings and escape curves as JSON: the text, or written to
        ``path_or_file`` (a path, written whole, or an open text file; then that is returned),
        as every ``to_csv`` and ``to_json`` of jaxarm does."""
        return write_or_return(path_or_file, text_writer(json.dumps({
            "problem": self.problem_name,
            "collision": self.collision,
            "n_particles": self.n_particles,
            "n_iters": self.n_iters,
            "base_seed": self.seed,
            "methods": [
                m.summary() | {"escape_curve": m.escape_curve().round(6).tolist()}
                for m in self.methods
            ],
            "comparisons": [c._asdict() for c in self.comparisons()],
        }, indent=2)))

    def records(self) -> list[dict]:
        """Tidy per-seed rows: one per (method, restart). Restart ``restart`` is seeded by
        ``(base_seed, restart)``: ``solve(problem, method, seed=base_seed)``'s restart of that
        index."""
        rows = []
        for m in self.methods:
            for i in range(m.n_restarts):
                rows.append({
                    "problem": self.problem_name,
                    "method": m.variant.label,
                    "constraint": m.variant.constraint,
                    "collision": self.collision,  # the check that decided "escaped"
                    "base_seed": self.seed,
                    "restart": int(m.restart_ids[i]),
                    "escaped": bool(m.escaped[i]),
                    "escape_iter": int(m.outcome.escape_iter[i]),
                    "best_fitness": float(m.outcome.best_fitness[i]),
                    "best_violation": float(m.outcome.best_violation[i]),
                    **{f"x{j}": float(v) for j, v in enumerate(m.outcome.best_x[i])},
                })
        return rows

    def to_csv(self, path_or_file=None) -> str | pathlib.Path:
        """``records()`` as CSV: the text, or written to ``path_or_file`` (a path, written
        whole, or an open text file; then that is returned)."""
        rows = self.records()
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
        return write_or_return(path_or_file, text_writer(out.getvalue()))


CHUNK_SIZE = 500  # seeds per compiled call of ``escape_study`` unless told
LOGGER = logging.getLogger("jaxarm.study")


def escape_study(problem: Problem, methods: Sequence = ("A", "B", "C"), *, n_restarts: int = 500,
                 n_iters: int = N_ITERS, n_particles: int | None = None, constraint: str = "death",
                 seed: int = 0, chunk_size: int = CHUNK_SIZE, checkpoint=None,
                 progress: bool | None = None) -> Study:
    """How often each method escapes zero fitness, over ``n_restarts`` independent seeds.

    Args:
      problem: the problem.
      methods: entries "A", "B", "C", "A:feasibility" (method:constraint),
        "A-ring[inertia_end=0.4]:feasibility" (``jaxarm.optim.methods``' names), ``PSOConfig``s,
        your own optimisers (``jaxarm.optim.custom``) or ``Variant``s
        (``methods.parse_methods``); labels must be unique.
      n_restarts: seeds (restarts) per method; the same restart indices for every method.
      n_iters: PSO iterations (paper: 100).
      n_particles: swarm size (paper: 20); None: your optimisers' population, else 20.
      constraint: the constraint rule for entries that do not name one.
      seed: base seed; seed i of the study is restart i of ``solve(problem, seed=seed)``.
      chunk_size: at most this many restarts per compiled call; the restarts are split into
        chunks of equal length (``padding.equal_chunk_length``; one program for all of them).
        Bounds memory and sets how often the progress bar moves; results do not depend on it.
      checkpoint: a folder (created if need be) where each finished chunk is saved
        (``jaxarm.io.checkpoints``); the same call again, after an interruption, resumes
        from the saved chunks and returns the same bits as an uninterrupted run. Another
        chunk size or number of restarts may resume it too; a checkpoint of another problem,
        method list, swarm, seed or version is refused with a ValueError naming what differs.
      progress: show a progress bar with the estimated time left (it moves once per chunk and
        says when a call compiles); default: when stderr is a terminal. Without the bar, a
        study of several chunks logs each finished chunk and the time left on the
        ``jaxarm.study`` logger (INFO; the ``jaxarm`` command shows it on stderr).

    Returns:
      ``Study``.

    Examples:
      >>> study = jaxarm.escape_study(jaxarm.load_scenario("paper-case-2"), ["A", "B"],
      ...                             n_restarts=4, n_iters=5, n_particles=6)
      >>> [(m.variant.label, m.n_restarts) for m in study.methods]
      [('A', 4), ('B', 4)]
    """
    check_problem(problem)
    variants = parse_methods(methods, constraint)
    n_particles = swarm_size(variants, n_particles, N_PARTICLES)
    n_restarts = positive_int("n_restarts", n_restarts)
    chunk_size = positive_int("chunk_size", chunk_size)
    check_search(n_particles=n_particles, n_iters=n_iters, seed=seed, constraint=constraint,
                 restarts_at_once=equal_chunk_length(n_restarts, chunk_size))
    store = None if checkpoint is None else StudyCheckpoint.open(checkpoint, study_identity(
        problem, variants, n_particles=n_particles, n_iters=n_iters, seed=seed))
    saved = [store.saved(index, n_restarts) if store else SavedRestarts(None, 0, 0.0, 0.0)
             for index in range(len(variants))]
    bar = _StudyProgress(problem.name, len(variants) * n_restarts, n_methods=len(variants),
                         done=sum(s.count for s in saved),
                         shown=sys.stderr.isatty() if progress is None else progress)
    run = dict(n_particles=n_particles, n_iters=n_iters, seed=seed,
               size=equal_chunk_length(n_restarts, chunk_size))
    results = tuple(_method_study(problem, variant, n_restarts, saved[index], bar,
                                  save=store and functools.partial(store.save, index), **run)
                    for index, variant in enumerate(variants))
    bar.close()
    return Study(problem.name, problem.collision, n_particles, n_iters, seed, results)


def _method_study(problem: Problem, variant: Variant, n_restarts: int, saved: SavedRestarts,
                  bar: _StudyProgress, *, n_particles: int, n_iters: int, seed: int, size: int,
                  save) -> MethodStudy:
    """One method's restarts after the ``saved`` ones, chunk by chunk, each chunk ``save``d
    (when given) as it finishes."""
    bar.describe(variant.label)
    parts = [] if saved.outcome is None else [saved.outcome]
    seconds, compiling = saved.seconds, saved.compile_seconds
    for start in range(saved.count, n_restarts, size):
        began = time.perf_counter()
        bar.compiling(not is_compiled(problem, variant.config, n_particles, n_iters, size))
        with compile_time() as chunk_compiling:
            # every chunk runs ``size`` restarts (one program); the last keeps what it needs
            outcome = run_restarts(problem, variant.config, variant.constraint,
                                   n_particles=n_particles, n_iters=n_iters, seed=seed,
                                   first_restart=start, n_restarts=size)
            part = RestartOutcome(*(np.asarray(field)[:n_restarts - start] for field in outcome))
        chunk_seconds = time.perf_counter() - began
        if save:
            save(start, part, chunk_seconds, chunk_compiling.seconds)
        parts.append(part)
        seconds, compiling = seconds + chunk_seconds, compiling + chunk_compiling.seconds
        bar.finished(len(part.best_fitness), seconds=chunk_seconds - chunk_compiling.seconds,
                     restarts_run=size, method_done=start + size >= n_restarts)
    return MethodStudy(variant=variant, restart_ids=np.arange(n_restarts),
                       outcome=parts[0].concatenate(*parts[1:]), seconds=seconds,
                       compile_seconds=compiling)


class _StudyProgress:
    """A study's progress: a bar with the time left on a terminal, else a line per finished
    chunk on the ``jaxarm.study`` logger (when the study has more than one chunk). ``total``
    and ``done`` count every method's seeds."""

    def __init__(self, name: str, total: int, *, n_methods: int, done: int, shown: bool):
        self.name, self.total, self.done, self.shown = name, total, done, shown
        self.n_methods = n_methods
        self.bar = _progress_bar(total, name, shown, initial=done)
        self.label = ""
        if done:
            LOGGER.info("%s: resuming from the checkpoint, %s of %s seeds saved", name,
                        f"{done:,}", f"{total:,}")

    def describe(self, label: str) -> None:
        self.label = label
        self.bar.set_description(f"{self.name} {label}")

    def compiling(self, compiling: bool) -> None:
        self.bar.set_postfix_str("compiling" if compiling else "")

    def finished(self, count: int, *, seconds: float, restarts_run: int,
                 method_done: bool) -> None:
        """``count`` more seeds done, in a chunk that ran ``restarts_run`` restarts in
        ``seconds`` apart from compiling (the method's last when ``method_done``): the time
        left assumes the rest run as fast."""
        self.done += count
        self.bar.update(count)
        if self.shown or count == self.total:  # shown by the bar, or a one-chunk study
            return
        left = (self.total - self.done) * seconds / restarts_run
        counted = f"{self.done:,} of {self.total:,} seeds"
        if self.n_methods > 1:
            state = "done" if method_done else "running"
            line = f"{self.name}: {counted} of {self.n_methods} methods ({self.label} {state})"
        else:
            line = f"{self.name} {self.label}: {counted}"
        LOGGER.info("%s, %s", line, f"about {_duration(left)} left" if left else "done")

    def close(self) -> None:
        self.bar.close()


def _progress_bar(total: int, label: str, enabled: bool, initial: int = 0):
    from tqdm import tqdm  # text bar: tqdm.auto warns in notebooks without ipywidgets

    return tqdm(total=total, initial=initial, desc=label, unit="seed", disable=not enabled,
                file=sys.stderr, leave=False)


def _duration(seconds: float) -> str:
    """``seconds`` as "2 h 05 min", "3 min 20 s" or "40 s"."""
    seconds = round(seconds)
    if seconds >= 3600:
        return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"
    if seconds >= 60:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{max(seconds, 1)} s"


def sweep_coefficient(problem: Problem, x, index: int, values) -> np.ndarray:
    """Fitness as one free coefficient sweeps through ``values``, the others fixed (Table 5).

    Args:
      x: the base coefficients, shape (n_free,).
      index: which coefficient to vary.
      values: shape (n_values,).

    Returns:
      Fitness, shape (n_values,).
    """
    x = np.asarray(x, dtype=np.float64)
    if not 0 <= index < problem.n_free:
        raise ValueError(f"index must be in [0, {problem.n_free}), got {index}")
    batch = np.repeat(x[None], len(values), axis=0)
    batch[:, index] = values
    return np.asarray(fitness(problem, batch))


def feasible_intervals(values, feasible) -> list[tuple[float, float]]:
    """Maximal runs of consecutive feasible sweep values, as (first, last) pairs."""
    values, feasible = np.asarray(values), np.asarray(feasible, dtype=bool)
    edges = np.diff(np.concatenate([[0], feasible.astype(int), [0]]))
    starts, stops = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
    return [(float(values[a]), float(values[b])) for a, b in zip(starts, stops)]
