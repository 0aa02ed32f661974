"""Escape-study wall time: 1000 seeds x 20 particles x 100 iterations on paper-case-1.

First call (compilation + run) and later calls (run only, median), scaling with the number of
restarts, and a check that a new scenario with the same sizes does not recompile.

    .venv/bin/python benchmarks/escape_bench.py [--repeats 3] [--max-restarts 10000]
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

import jaxarm
from jaxarm.solve import compiled_search


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

    run = lambda problem, n, seed=0: jaxarm.solve(problem, "A", n_restarts=n, seed=seed)  # noqa: E731
    first = timed(lambda: run(case1, 1000))
    later = float(np.median([timed(lambda: run(case1, 1000, seed=s + 1))
                             for s in range(args.repeats)]))
    print(f"\n1000 seeds x 20 particles x 100 iterations: first call {first:.2f} s "
          f"(compilation about {first - later:.2f} s), later calls {later:.2f} s (median of "
          f"{args.repeats}), {1000 * 20 * 101 / later:,.0f} path evaluations per second")

    cached = compiled_search._cache_size()
    other = case1.replace(world=jaxarm.World(boxes=[((30.0, 2.0), (68.0, 28.0))]),
                          init_low=-50.0, init_high=50.0)
    second_scenario = timed(lambda: run(other, 1000))
    recompiled = compiled_search._cache_size() - cached
    print(f"A different obstacle and init range, same sizes: {second_scenario:.2f} s, "
          f"{recompiled} new compilation(s)")

    print("\n| restarts | seconds (run only) | restarts per second | path evaluations per second |")
    print("|---|---|---|---|")
    n = 10
    while n <= args.max_restarts:
        run(case1, n)  # compile this size
        seconds = float(np.median([timed(lambda: run(case1, n, seed=s + 1))
                                   for s in range(args.repeats)]))
        print(f"| {n:,} | {seconds:.3f} | {n / seconds:,.0f} | {n * 20 * 101 / seconds:,.0f} |")
        n *= 10


if __name__ == "__main__":
    main()
