"""Path degree 6 vs 7 vs 8 on a hard scene: escape rate, fitness and the paths' shape.

For each scenario, degree and method (default: death-trap under the certified check, preset A
with feasibility rules and the ring whose inertia falls to 0.4): the escape rate over
``--seeds`` restarts with its 95 % Wilson interval, the median and best final fitness of the
restarts that escaped, and, over their best paths, the median joint-space length (integral of
|dtheta/dr|) and maximum jerk (max |d^3 theta / dr^3|), the metrics of ``benchmarks/peers.py``
(where OMPL RRTConnect's paths are measured the same way). Times include compilation.

    .venv/bin/python benchmarks/degree_bench.py [--seeds 300] [--scenarios death-trap]
        [--degrees 6,7,8] [--methods "A:feasibility,A-ring[inertia_end=0.4]:feasibility"]
        [--collision certified]
"""

from __future__ import annotations

import argparse
import platform

import jax
import numpy as np
from peers import path_metrics  # the metrics OMPL's paths are measured by

import jaxarm
from jaxarm.choices import split_methods

METHODS = "A:feasibility,A-ring[inertia_end=0.4]:feasibility"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=300)
    parser.add_argument("--scenarios", default="death-trap")
    parser.add_argument("--degrees", default="6,7,8")
    parser.add_argument("--methods", default=METHODS)
    parser.add_argument("--collision", default="certified", choices=("sampled", "certified"))
    args = parser.parse_args()
    print(f"jax {jax.__version__} ({jax.default_backend()}), "
          f"{platform.processor() or platform.machine()}, "
          f"{args.restarts} seeds x 20 particles x 100 iterations, {args.collision} check\n")
    print("| scenario | degree | free | method | escape rate [95 % CI] | median / best fitness "
          "| median length (rad) | median max jerk | time (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        base = jaxarm.load_scenario(name, collision=args.collision)
        for degree in map(int, args.degrees.split(",")):
            problem = base.replace(degree=degree)
            study = jaxarm.escape_study(problem, split_methods(args.methods),
                                        n_restarts=args.restarts, progress=False)
            for method in study.methods:
                s, outcome = method.summary(), method.outcome
                escaped = outcome.best_x[outcome.feasible]
                if len(escaped):
                    length, jerk = path_metrics(problem, escaped)
                    shape = f"{np.median(length):.3f} | {np.median(jerk):.0f}"
                    fitness = f"{s['fitness_median']:.4f} / {s['fitness_best']:.4f}"
                else:
                    shape, fitness = "– | –", "–"
                print(f"| {name} | {degree} | {problem.n_free} | {method.variant.label} | "
                      f"{s['escape_rate']:.1%} [{s['ci95_low']:.1%}, {s['ci95_high']:.1%}] | "
                      f"{fitness} | {shape} | {s['seconds']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
