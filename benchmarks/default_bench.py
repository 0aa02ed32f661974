"""What ``solve(problem)`` with no options finds: a certified path in every call?

For every shipped scenario (or ``--scenarios``): ten default calls, ``solve(problem, seed=s)`` for
s = 0..9 (the certified check, the scenario's own settings), how many end certified
collision-free, their median and worst fitness, and the median against the best path that
``--restarts`` restarts of each of the default's methods (the ring and preset A, with feasibility
rules) find, together. Then the time of a warm default call on paper-case-1
(median of 5, after one call that compiles).

    .venv/bin/python benchmarks/default_bench.py [--seeds 10] [--restarts 200]
        [--scenarios a,b,...]

``--hard [--seeds 3]`` instead runs the default on scenes where its first stage finds nothing
(``hard_scenes``) and on one with no path at all: how many calls end certified within the
time limit, at which degree, and how long they took, compiling included (each scene's first
call in a fresh process compiles what the scenes before it did not).
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
    """Scenes where the default's first stage (degree 6, 16 restarts) certifies nothing, and
    one where no path exists (the first link walled in beside the base)."""
    five = jaxarm.load_scenario("five-link-detour").replace(world=jaxarm.World(), margin=1.0)
    return {
        **{f"five-link-detour arm, 25 circles (seed {seed}), margin 1 cm":
           jaxarm.clutter(five, 25, "circles", size=(3.0, 6.0), seed=seed)
           for seed in HARD_CLUTTER_SEEDS},
        **{f"{name}, margin {margin:g} cm": jaxarm.load_scenario(name).replace(margin=margin)
           for name, margin in HARD_MARGINS},
        "impossible: the first link walled in": jaxarm.Problem(
            arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=[0.0, 0.5, 0.5],
            goal=[np.pi, -0.5, -0.5], name="walled-in",
            world=jaxarm.World(boxes=[((-2.0, 4.0), (2.0, 10.0)),
                                      ((-2.0, -10.0), (2.0, -4.0))])),
    }


HARD_CLUTTER_SEEDS = ()  # filled from the exploration below
HARD_MARGINS = ()


def hard_row(name: str, problem, n_seeds: int) -> str:
    calls = []
    for seed in range(n_seeds):
        began = time.perf_counter()
        result = jaxarm.solve(problem, seed=seed, progress=False)
        calls.append((result, time.perf_counter() - began))
    certified = sum(result.certified for result, _ in calls)
    degrees = sorted({result.degree for result, _ in calls if result.certified})
    stages = [len(result.stages) for result, _ in calls]
    seconds = [elapsed for _, elapsed in calls]
    return (f"| {name} | {certified}/{n_seeds} | {', '.join(map(str, degrees)) or '-'} | "
            f"{min(stages)}-{max(stages)} | {statistics.median(seconds):.0f} | "
            f"{max(seconds):.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--scenarios", default=",".join(available()))
    parser.add_argument("--hard", action="store_true")
    args = parser.parse_args()
    if args.hard:
        print(f"solve(problem, seed=s), s = 0..{args.seeds - 1}, the default (time limit "
              f"{DEFAULT_TIME_LIMIT:g} s); jax {jax.__version__} on "
              f"{jax.devices()[0].platform}\n")
        print("| scene | calls certified free | degrees found | stages run | median s | "
              "longest s |")
        print("|---|---|---|---|---|---|")
        for name, problem in hard_scenes().items():
            print(hard_row(name, problem, args.seeds), flush=True)
        return
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
