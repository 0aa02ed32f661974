"""What ``solve(problem)`` with no options finds: a certified path in every call?

For every shipped scenario (or ``--scenarios``): ten default calls, ``solve(problem, seed=s)`` for
s = 0..9 (the certified check, the scenario's own settings), how many end certified
collision-free, their median and worst fitness, and the median against the best path that
``--restarts`` restarts of each of the default's methods (the ring and preset A, with feasibility
rules) find, together. Then the time of a warm default call on paper-case-1
(median of 5, after one call that compiles).

    .venv/bin/python benchmarks/default_bench.py [--seeds 10] [--restarts 200]
        [--scenarios a,b,...]
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import numpy as np

import jaxarm
from jaxarm.choices import DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--scenarios", default=",".join(available()))
    args = parser.parse_args()
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
