"""Sampled "feasible" against really collision-free, and what a certified search finds.

For each scenario: ``solve(problem, "A", constraint="feasibility", n_restarts=N, seed=0)`` with
the paper's sampled check, each restart's best path measured by the dense shapely oracle
(``jaxarm.testing``, 4,001 points of r); then the same search with the certified check (the
default), its escape rate, the best fitness, the share of restarts it certifies, and its time
beside the sampled search's. Prints a Markdown table for ``benchmarks/RESULTS.md``.

    python benchmarks/certified_bench.py [--restarts 100] [--scenarios a,b,...]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import jaxarm
from jaxarm.testing import dense_clearance

SCENARIOS = ("paper-case-1", "paper-case-2", "paper-case-3", "narrow-gap", "thin-wall",
             "overhead-shelf", "five-link-detour")


def timed_solve(problem, n_restarts):
    """Solve twice (the first call compiles) and return the second result and its time."""
    jaxarm.solve(problem, "A", constraint="feasibility", n_restarts=n_restarts, seed=0)
    began = time.perf_counter()
    result = jaxarm.solve(problem, "A", constraint="feasibility", n_restarts=n_restarts, seed=0)
    return result, time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=100)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = parser.parse_args()
    print(f"| scenario | sampled: feasible best paths | of them really free (oracle) | "
          f"sampled best fitness, really free | certified: escape | certified best fitness | "
          f"oracle-free of certified | time sampled / certified ({args.restarts} restarts) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        problem = jaxarm.load_scenario(name)
        sampled, sampled_time = timed_solve(problem.replace(collision="sampled"), args.restarts)
        feasible = sampled.restarts.best_violation == 0
        clear = dense_clearance(problem, sampled.restarts.best_x) >= 0
        really = feasible & clear
        best_free = float(np.max(np.where(really, sampled.restarts.best_fitness, 0.0)))
        certified, certified_time = timed_solve(problem, args.restarts)
        escaped = certified.restarts.best_violation == 0
        oracle = dense_clearance(problem, certified.restarts.best_x[escaped]) >= 0
        print(f"| {name} | {feasible.sum()} | {really.sum()} | {best_free:.4f} | "
              f"{escaped.mean():.0%} | {certified.best_fitness:.4f} | "
              f"{oracle.sum()}/{escaped.sum()} | {sampled_time:.1f} s / {certified_time:.1f} s |",
              flush=True)


if __name__ == "__main__":
    main()
