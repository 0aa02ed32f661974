"""What ``solve(problem)`` with no options finds: a certified path in every call?

For every shipped scenario (or ``--scenarios``): ten default calls, ``solve(problem, seed=s)`` for
s = 0..9 (the certified check, the scenario's own settings), how many end certified
collision-free, their median and worst fitness, and the median against the best path that
``--restarts`` restarts of each of the default's methods (the ring and preset A, with feasibility
rules) find, together. Then the time of a warm default call on paper-case-1
(median of 5, after one call that compiles).

    .venv/bin/python benchmarks/default_bench.py [--seeds 10] [--restarts 200]
        [--scenarios a,b,...]

``--hard [--seeds 2]`` instead runs the default, time limit and all, on harder scenes
(``hard_scenes``): a margin on the shelf, a 5-link arm among 25 circles with a 1 cm margin
(built around a degree-8 path kept clear, so a free path exists), and one with no path (the
first link walled in beside the base): how many calls end certified, at which degree, after
how many stages and how long, compiling included (each call after the first of a scene reuses
its programs).
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import numpy as np

import jaxarm
from jaxarm.choices import (DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS,
                            DEFAULT_TIME_LIMIT)
from jaxarm.io.scenario_files import available

REFERENCE_METHODS = tuple(f"{method}:{DEFAULT_CONSTRAINT}" for method in DEFAULT_METHODS)


def scenario_row(name: str, n_seeds: int, n_restarts: int) -> str:
    problem = jaxarm.load_scenario(name)
    calls = [jaxarm.solve(problem, seed=seed) for seed in range(n_seeds)]
    certified = [call.certified for call in calls]
    fitness = np.array([call.best_fitness for call in calls])
    reference = max(jaxarm.solve(problem, method, n_restarts=n_restarts, seed=0).best_fitness
                    for method in REFERENCE_METHODS)
    median = float(np.median(fitness))
    return (f"| {name} | {sum(certified)}/{n_seeds} | {median:.4f} | {fitness.min():.4f} | "
            f"{reference:.4f} | {median / reference - 1:+.1%} |")


def warm_call_seconds(repeats: int = 5) -> float:
    problem = jaxarm.load_scenario("paper-case-1")
    jaxarm.solve(problem)
    times = []
    for seed in range(repeats):
        began = time.perf_counter()
        jaxarm.solve(problem, seed=seed)
        times.append(time.perf_counter() - began)
    return statistics.median(times)


def hard_scenes() -> dict:
    """The ``--hard`` scenes by name (module docstring)."""
    five = jaxarm.load_scenario("five-link-detour").replace(world=jaxarm.World(), margin=1.0,
                                                           degree=8)
    kept_clear = np.random.default_rng(0).uniform(-100.0, 100.0, five.n_free)
    return {
        "overhead-shelf, margin 2 cm": jaxarm.load_scenario("overhead-shelf", margin=2.0),
        **{f"5 links, 25 circles (clutter seed {seed}), margin 1 cm": jaxarm.clutter(
            five, 25, "circles", size=(3.0, 6.0), seed=seed, clear_path=kept_clear
        ).replace(degree=6) for seed in (0, 1)},
        "no path: the first link walled in": jaxarm.Problem(
            arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=[0.0, 0.5, 0.5],
            goal=[np.pi, -0.5, -0.5], name="walled-in",
            world=jaxarm.World(boxes=[((-2.0, 4.0), (2.0, 10.0)),
                                      ((-2.0, -10.0), (2.0, -4.0))])),
    }


def hard_row(name: str, problem, n_seeds: int) -> str:
    calls = []
    for seed in range(n_seeds):
        began = time.perf_counter()
        result = jaxarm.solve(problem, seed=seed, progress=False)
        calls.append((result, time.perf_counter() - began))
    certified = sum(result.certified for result, _ in calls)
    degrees = sorted({result.degree for result, _ in calls if result.certified})
    stages = sorted({len(result.stages) for result, _ in calls})
    seconds = [elapsed for _, elapsed in calls]
    return (f"| {name} | {certified}/{n_seeds} | {', '.join(map(str, degrees)) or '-'} | "
            f"{', '.join(map(str, stages))} | {', '.join(f'{s:.0f}' for s in seconds)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None)
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--scenarios", default=",".join(available()))
    parser.add_argument("--hard", action="store_true")
    args = parser.parse_args()
    if args.hard:
        n_seeds = args.seeds or 2
        print(f"solve(problem, seed=s), s = 0..{n_seeds - 1}: the default, time limit "
              f"{DEFAULT_TIME_LIMIT:g} s; jax {jax.__version__} on "
              f"{jax.devices()[0].platform}\n")
        print("| scene | calls certified free | degree found | stages run | seconds per call |")
        print("|---|---|---|---|---|")
        for name, problem in hard_scenes().items():
            print(hard_row(name, problem, n_seeds), flush=True)
        return
    args.seeds = args.seeds or 10
    print(f"solve(problem, seed=s), s = 0..{args.seeds - 1}: {DEFAULT_RESTARTS} restarts each "
          f"of {' and '.join(DEFAULT_METHODS)} under {DEFAULT_CONSTRAINT} rules, certified check; "
          f"reference: "
          f"the best of {args.restarts} restarts each of {', '.join(REFERENCE_METHODS)}; "
          f"jax {jax.__version__} on {jax.devices()[0].platform}\n")
    print("| scenario | calls certified free | median fitness | worst fitness | reference best "
          "| median vs reference |")
    print("|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        print(scenario_row(name, args.seeds, args.restarts), flush=True)
    print(f"\nWarm default call on paper-case-1 (median of 5): {warm_call_seconds():.2f} s")


if __name__ == "__main__":
    main()
