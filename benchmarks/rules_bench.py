"""Constraint rules and topologies on the hard scenarios, and the feasible share of every one.

For paper-case-1 and death-trap, in each collision mode: escape rate (CEC 2006's feasible
rate) with its 95 % interval, the share that ends feasible, the median and best final fitness of
the feasible restarts, and each row against the death penalty (Newcombe interval, Fisher p).
Then every shipped scenario's feasible share of the init range, with the iteration-0 escape it
predicts for 20 particles beside the one measured.

    .venv/bin/python benchmarks/rules_bench.py [--seeds 300] [--modes sampled,certified]
"""

from __future__ import annotations

import argparse

import jax

import jaxarm
from jaxarm.reproduce import rule_methods


def rules_table(problem, n_seeds: int) -> list[str]:
    result = jaxarm.escape_study(problem, rule_methods()[0], n_seeds=n_seeds, progress=False)
    lines = []
    for method in result.methods:
        s, outcome = method.summary(), method.outcome
        versus = "–"
        if method.variant.label != "A":
            c = result.compare(method.variant.label, "A")
            versus = f"{c.difference_text()}, p = {c.p_value:.2g}"
        median = ("–" if s["fitness_median"] is None
                  else f"{s['fitness_median']:.4f} / {s['fitness_best']:.4f}")
        lines.append(f"| {problem.name} | {problem.collision} | {method.variant.label} | "
                     f"{s['escape_rate']:.1%} [{s['ci95_low']:.1%}, {s['ci95_high']:.1%}] | "
                     f"{outcome.feasible.mean():.1%} | {median} | {versus} | "
                     f"{s['seconds']:.1f} |")
    return lines


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=300)
    parser.add_argument("--modes", default="sampled,certified")
    args = parser.parse_args()
    modes = args.modes.split(",")
    print(f"jax {jax.__version__} ({jax.default_backend()}), {args.seeds} seeds, preset A, "
          "20 particles, 100 iterations\n")
    print("| scenario | check | rule | escape rate [95 % CI] | ends feasible | "
          "median / best fitness (feasible) | vs death penalty | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for mode in modes:
        for name in ("paper-case-1", "death-trap"):
            for line in rules_table(jaxarm.load_scenario(name, collision=mode), args.seeds):
                print(line, flush=True)
    print("\n| scenario | check | free share [95 % CI] | start escape: predicted / measured |")
    print("|---|---|---|---|")
    for mode in modes:
        for name in jaxarm.available_scenarios():
            problem = jaxarm.load_scenario(name, collision=mode)
            share = jaxarm.feasible_fraction(problem, n_samples=10_000)
            measured = jaxarm.escape_study(problem, ["A"], n_seeds=args.seeds, n_iters=1,
                                           progress=False)["A"].start_escape_rate()
            predicted, (low, high) = share.start_escape(20)
            print(f"| {name} | {mode} | {share.fraction:.2%} [{share.interval[0]:.2%}, "
                  f"{share.interval[1]:.2%}] | {predicted:.1%} [{low:.1%}, {high:.1%}] / "
                  f"{measured:.1%} |", flush=True)


if __name__ == "__main__":
    main()
