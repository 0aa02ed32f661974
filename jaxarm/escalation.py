"""The anytime search behind ``solve``: stages of restarts, then higher degrees, under a time limit.

Stage 0 is the call as asked (the default's 8 + 8 restarts at the problem's degree: the same
bits as a search without a time limit). While no restart has a certified-free path and time is
left, the next stage of ``stage_plan`` runs: as many restarts again at the same degree (new
seeds), then each higher degree (by 2, up to ``MAX_DEGREE``) seeded with the best paths found
so far raised to it (``raise_degree``: the same motions, so a stage starts where the last one
got to), first with the stage-0 restarts, then three times as many. The plan spends little on
more restarts before it climbs: at degree 6 a joint's path has one free coefficient, so more
swarms search the same small family of paths, and a higher degree is what adds shapes.

A stage runs in chunks of stage 0's size (one compiled program per degree and method; a later
stage stops at its first chunk with a certified path), and starts only when it is expected to
end within the time limit (``_ChunkClock``: the chunks' times at that degree, or at a new
degree the last degree's, scaled up, and its compiling). Stages run whole or not at all and
come in a fixed order, so a seed gives the same stages on any machine; the time limit only
decides how many run, and ``max_stages`` repeats a run stage for stage.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from typing import Callable, NamedTuple

import numpy as np

from jaxarm._compile import timing
from jaxarm.checks.evaluate import certify
from jaxarm.choices import MAX_DEGREE
from jaxarm.model.path import raise_degree
from jaxarm.model.problem import Problem
from jaxarm.optim import evosax_adapter
from jaxarm.optim.custom import CustomConfig
from jaxarm.optim.restarts import RestartOutcome, run_restarts

LOGGER = logging.getLogger("jaxarm.search")
MORE_RESTARTS = 3  # a higher degree's second stage runs this many times the stage-0 restarts
SEEDS = 4  # best paths so far given to every swarm of a higher degree
COMPILE_FLOOR = 1.5  # s per degree and method: compiling a search program not yet compiled


class StagePlan(NamedTuple):
    """One stage of the anytime search."""

    degree: int
    n_restarts: int  # per method
    seeded: bool  # its swarms start with the best paths so far, raised to ``degree``


class Stage(NamedTuple):
    """What a stage did: the progress report, and the summary's record."""

    index: int
    degree: int
    n_restarts: int  # run, all methods (fewer than planned when a chunk certified a path)
    seeded: bool
    escaped: int  # restarts whose best path is collision-free under the problem's check
    certified: bool  # one of them proved free for every r
    best_fitness: float  # the best certified path's fitness so far (0: none yet)
    best_violation: float  # the least violation of this stage's restarts (cm, plus rad
    #   outside a joint's limits)
    seconds: float  # since the call began, at the stage's end
    time_left: float  # s (inf without a limit)
    time_ran_out: bool  # the next stage was not expected to end within the time left

    def line(self) -> str:
        """One line for a log or a terminal."""
        found = (f"best certified fitness {self.best_fitness:.5g}" if self.best_fitness > 0
                 else f"nothing certified yet (least violation {self.best_violation:.3g})")
        left = ("" if math.isinf(self.time_left) else f", {self.time_left:.0f} s left"
                if self.time_left >= 0 else f", {-self.time_left:.0f} s past the time limit")
        return (f"stage {self.index}: degree {self.degree}, {self.n_restarts} restart(s)"
                f"{' seeded' if self.seeded else ''}"
                f", {self.escaped} escaped; {found}; {self.seconds:.1f} s{left}")


def stage_plan(degree: int, n_restarts: int) -> list[StagePlan]:
    """The stages in order from a problem's degree and the stage-0 restarts per method."""
    plan = [StagePlan(degree, n_restarts, False), StagePlan(degree, n_restarts, False)]
    for higher in range(degree + 2, MAX_DEGREE + 2, 2):
        higher = min(higher, MAX_DEGREE)
        if higher > plan[-1].degree:
            plan += [StagePlan(higher, n_restarts, True),
                     StagePlan(higher, MORE_RESTARTS * n_restarts, True)]
    return plan


def at_degree(problem: Problem, degree: int) -> Problem:
    """The problem at another degree; a per-coefficient init range gives the new powers the
    range of its highest power."""
    if degree == problem.degree:
        return problem
    bounds = {}
    for name in ("init_low", "init_high"):
        value = getattr(problem, name)
        if np.ndim(value):
            per_power = np.asarray(value).reshape(-1, problem.n_joints)
            extra = np.repeat(per_power[-1:], degree - problem.degree, axis=0)
            bounds[name] = tuple(np.concatenate([per_power, extra]).ravel().tolist())
    return problem.replace(degree=degree, **bounds)


class Escalation(NamedTuple):
    """What the stages found: the restarts at the degree of the best path, and the stages."""

    problem: Problem  # at the degree of the best path
    outcome: RestartOutcome  # every restart run at that degree
    variant: np.ndarray  # shape=(n_restarts,), int: which method ran each
    n_restarts: tuple  # per method at that degree
    certified: np.ndarray  # shape=(n_restarts,), bool
    stages: tuple  # of ``Stage``


class _Best(NamedTuple):
    score: float
    degree: int


def escalate(problem: Problem, variants: list, constraint: str, *, n_particles: int,
             n_iters: int, n_restarts: int, seed: int, init_particles, time_limit: float,
             max_stages: int | None, improve: bool, progress: Callable | None,
             began: float) -> Escalation:
    """Run ``stage_plan``'s stages (module docstring) until a certified path is found (or, with
    ``improve``, until the time or the plan runs out), at most ``max_stages``. Stage 0 always
    runs; a later one only when it is expected to end within the time limit, and it stops at
    its first chunk with a certified path unless ``improve``."""
    plan = stage_plan(problem.degree, n_restarts)[:max_stages]
    deadline = began + time_limit
    by_degree: dict[int, list] = {}  # degree -> [(outcome, variant, certified)]
    clock = _ChunkClock(len(variants))
    stages, next_restart, seeds, best = [], 0, None, _Best(-math.inf, problem.degree)
    for index, stage in enumerate(plan):
        chunks = [(i, chunk) for chunk in range(stage.n_restarts // n_restarts)
                  for i in range(len(variants))]
        if index and time.perf_counter() + clock.expected(stage.degree, len(chunks)) > deadline:
            stages[-1] = stages[-1]._replace(time_ran_out=True)
            break
        staged = at_degree(problem, stage.degree)
        given = init_particles if index == 0 else (
            raise_degree(seeds[0][:n_particles], problem.n_joints, stage.degree)
            if stage.seeded and _takes_seeds(variants) else None)
        ran = []
        for i, chunk in chunks:
            if index and ran and ran[-1][2].any() and not improve:
                break
            outcome = clock.timed(stage.degree, functools.partial(
                run_restarts, staged, variants[i].config, constraint, n_particles=n_particles,
                n_iters=n_iters, seed=seed, n_restarts=n_restarts, init_particles=given,
                first_restart=next_restart + i * stage.n_restarts + chunk * n_restarts))
            ran.append((outcome, np.full(n_restarts, i), _certified(staged, outcome)))
        next_restart += len(variants) * stage.n_restarts
        by_degree.setdefault(stage.degree, []).extend(ran)
        outcomes = RestartOutcome(*(np.concatenate(parts) for parts in
                                    zip(*(outcome for outcome, _, _ in ran))))
        certified = np.concatenate([c for _, _, c in ran])
        score = float(np.max(np.where(certified, outcomes.best_fitness, -math.inf)))
        if score > best.score:
            best = _Best(score, stage.degree)
        seeds = _best_paths(seeds, outcomes, problem.n_joints, stage.degree)
        now = time.perf_counter()
        stages.append(Stage(index, stage.degree, len(ran) * n_restarts,
                            given is not None and index > 0, int(outcomes.feasible.sum()),
                            bool(certified.any()), max(best.score, 0.0),
                            float(outcomes.best_violation.min()), now - began, deadline - now,
                            False))
        _report(progress, stages[-1])
        if best.score > -math.inf and not improve:
            break
    degree = best.degree if best.score > -math.inf else _least_violation_degree(by_degree)
    runs = by_degree[degree]
    outcome = RestartOutcome(*(np.concatenate(parts) for parts in zip(*(o for o, _, _ in runs))))
    return Escalation(at_degree(problem, degree), outcome, np.concatenate([v for _, v, _ in runs]),
                      tuple(np.bincount(np.concatenate([v for _, v, _ in runs]),
                                        minlength=len(variants)).tolist()),
                      np.concatenate([c for _, _, c in runs]), tuple(stages))


class _ChunkClock:
    """How long chunks of restarts took at each degree, running and compiling apart
    (``timing.compile_time``), and what a stage is expected to take: its chunks at the latest
    run time of that degree, or at a new degree the last degree's scaled by (degree + 1)^2 (how
    the certified check's work grows), plus the last degree's compiling scaled by
    ((degree + 1) / (last + 1))^1.5 and at least ``COMPILE_FLOOR`` s per degree and method
    (compiling time grows about so with the degree: ``benchmarks/RESULTS.md``, *Path degree
    limit*)."""

    def __init__(self, n_methods: int):
        self.n_methods = n_methods
        self.run: dict[int, float] = {}  # degree -> the latest chunk's run time
        self.compile: dict[int, float] = {}  # degree -> compiling at that degree, summed

    def timed(self, degree: int, call):
        """``call()``, timed."""
        began = time.perf_counter()
        with timing.compile_time() as compiling:
            result = call()
        self.run[degree] = max(time.perf_counter() - began - compiling.seconds, 0.0)
        self.compile[degree] = self.compile.get(degree, 0.0) + compiling.seconds
        return result

    def expected(self, degree: int, n_chunks: int) -> float:
        """Seconds ``n_chunks`` chunks at ``degree`` are expected to take."""
        if degree in self.run:
            return n_chunks * self.run[degree]
        last = max(self.run)
        ratio = (degree + 1) / (last + 1)
        compiling = max(self.compile[last] * ratio**1.5, COMPILE_FLOOR * degree * self.n_methods)
        return compiling + n_chunks * self.run[last] * ratio**2


def _takes_seeds(variants) -> bool:
    return not any(isinstance(v.config, (evosax_adapter.StrategyConfig, CustomConfig))
                   for v in variants)


def _certified(problem: Problem, outcome: RestartOutcome) -> np.ndarray:
    """Which restarts' best paths are known proved free for every r: under the certified check
    every feasible one (the search's own proofs); under the sampled check the fittest feasible
    one, if ``certify`` proves it (one path: the program ``solve`` certifies its best with)."""
    feasible = outcome.feasible
    if problem.collision == "certified" or not feasible.any():
        return feasible
    fittest = int(np.argmax(np.where(feasible, outcome.best_fitness, -np.inf)))
    proved = np.zeros_like(feasible)
    proved[fittest] = bool(certify(problem, outcome.best_x[fittest]).free)
    return proved


def _best_paths(seeds, outcome: RestartOutcome, n_joints: int, degree: int):
    """The ``SEEDS`` best paths of the seeds so far and this outcome (free and fittest
    first, then the least violation), at ``degree``."""
    x = outcome.best_x
    score = np.where(outcome.feasible, outcome.best_fitness, -outcome.best_violation)
    if seeds is not None:
        x = np.concatenate([raise_degree(seeds[0], n_joints, degree), x])
        score = np.concatenate([seeds[1], score])
    order = np.argsort(-score, kind="stable")[:SEEDS]
    return x[order], score[order]


def _least_violation_degree(by_degree: dict) -> int:
    return min(by_degree, key=lambda d: min(float(o.best_violation.min())
                                           for o, _, _ in by_degree[d]))


def _report(progress, stage: Stage) -> None:
    if progress is None:
        LOGGER.info(stage.line())
    elif progress is not False:
        progress(stage)
