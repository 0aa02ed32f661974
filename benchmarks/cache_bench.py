"""The persistent compilation cache: a fresh process's first ``solve``, cold and warm cache.

Each measurement is a new Python process (``JAXARM_CACHE_DIR`` pointing at a scratch folder)
that times its own first ``jaxarm.solve`` (preset A, 20 x 100, paper-case-1) after import and
loading. Cold: an empty folder; warm: the folder the cold run filled (median of the repeats).
With ``--demo``, also ``jaxarm reproduce-paper --quick`` twice on one folder (the second reads
what the first wrote).

    .venv/bin/python benchmarks/cache_bench.py [--repeats 3] [--demo]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

FIRST_SOLVE = """
import time, jaxarm
jaxarm.enable_compilation_cache()
problem = jaxarm.load_scenario("paper-case-1", collision={collision!r})
began = time.perf_counter()
jaxarm.solve(problem, "A", n_restarts={n_restarts})
print(time.perf_counter() - began)
"""


def first_solve(folder: str, collision: str, n_restarts: int) -> float:
    code = FIRST_SOLVE.format(collision=collision, n_restarts=n_restarts)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env=dict(os.environ, JAXARM_CACHE_DIR=folder))
    return float(done.stdout.split()[-1])


def demo(folder: str, out: str) -> float:
    began = time.perf_counter()
    subprocess.run([sys.executable, "-m", "jaxarm", "reproduce-paper", "--quick", "--out", out],
                   check=True, capture_output=True, env=dict(os.environ, JAXARM_CACHE_DIR=folder))
    return time.perf_counter() - began


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--demo", action="store_true")
    args = parser.parse_args()
    print("| first solve in a fresh process | cold cache (s) | warm cache, median (s) "
          "| warm / cold |")
    print("|---|---|---|---|")
    for collision, n_restarts in (("sampled", 1), ("certified", 1), ("certified", 100)):
        with tempfile.TemporaryDirectory() as folder:
            cold = first_solve(folder, collision, n_restarts)
            warm = np.median([first_solve(folder, collision, n_restarts)
                              for _ in range(args.repeats)])
        print(f"| {collision}, {n_restarts} restart(s) | {cold:.2f} | {warm:.2f} | "
              f"{warm / cold:.0%} |")
    if args.demo:
        with tempfile.TemporaryDirectory() as folder, tempfile.TemporaryDirectory() as out:
            first, second = demo(folder, out), demo(folder, out)
        print(f"\nreproduce-paper --quick: first {first:.0f} s, second {second:.0f} s "
              f"({second / first:.0%})")


if __name__ == "__main__":
    main()
