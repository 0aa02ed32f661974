"""Escape-study wall time: 1000 seeds x 20 particles x 100 iterations on paper-case-1.

First call (compilation + run) and later calls (run only, median) with the paper's sampled
check and the certified check (the default) side by side, scaling with the number of restarts
(sampled, and certified up to 1,000), and a check that a new scenario with the same sizes does
not recompile.

    .venv/bin/python benchmarks/escape_bench.py [--repeats 3] [--max-restarts 10000]
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

import jaxarm
from jaxarm.optim.restarts import compiled_search


def timed(run):
    began = time.perf_counter()
    run()
    return time.perf_counter() - began


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-restarts", type=int, default=10_000)
    args = parser.parse_args()
    case1 = jaxarm.load_scenario("paper-case-1")
    print(f"jax {jax.__version__} ({jax.default_backend()}, {len(jax.devices())} device(s))")

    def run(problem, n, seed=0):
        return jaxarm.solve(problem, "A", n_restarts=n, seed=seed)

    sampled = case1.replace(collision="sampled")
    later = {}
    for problem in (sampled, case1):
        first = timed(lambda: run(problem, 1000))
        later[problem.collision] = float(np.median([timed(lambda: run(problem, 1000, seed=s + 1))
                                                    for s in range(args.repeats)]))
        print(f"\n{problem.collision}: 1000 seeds x 20 particles x 100 iterations: first call "
              f"{first:.2f} s (compilation about {first - later[problem.collision]:.2f} s), later "
              f"calls {later[problem.collision]:.2f} s (median of {args.repeats}), "
              f"{1000 * 20 * 101 / later[problem.collision]:,.0f} path evaluations per second")
    print(f"certified / sampled time: {later['certified'] / later['sampled']:.1f}x")

    cached = compiled_search.programs_made()
    other = sampled.replace(world=jaxarm.World(circles=[(44.0, 6.0, 9.0), (-30.0, 30.0, 3.0)]),
                          init_low=-50.0, init_high=50.0)
    second_scenario = timed(lambda: run(other, 1000))  # sampled, as compiled above
    recompiled = compiled_search.programs_made() - cached
    print(f"A different obstacle and init range, same sizes: {second_scenario:.2f} s, "
          f"{recompiled} new compilation(s)")

    print("\n| check | restarts | seconds (run only) | restarts per second | "
          "path evaluations per second |")
    print("|---|---|---|---|---|")
    for problem, most in ((sampled, args.max_restarts), (case1, min(1000, args.max_restarts))):
        n = 10
        while n <= most:
            run(problem, n)  # compile this size
            seconds = float(np.median([timed(lambda: run(problem, n, seed=s + 1))
                                       for s in range(args.repeats)]))
            print(f"| {problem.collision} | {n:,} | {seconds:.3f} | {n / seconds:,.0f} | "
                  f"{n * 20 * 101 / seconds:,.0f} |", flush=True)
            n *= 10


if __name__ == "__main__":
    main()
