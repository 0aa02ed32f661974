"""Constraint rules and topologies on the hard scenarios, and the feasible share of every one.

For paper-case-1 and death-trap, in each collision mode: escape rate (CEC 2006's feasible
rate) with its 95 % interval, the share that ends feasible, the median and best final fitness of
the feasible restarts, and each row against the death penalty (Newcombe interval, Fisher p).
Then every shipped scenario's feasible share of the init range, with the iteration-0 escape it
predicts for 20 particles beside the one measured (the initial swarms of ``--start-seeds``
seeds, with the Wilson interval of that share).

The rules are ``reproduce-paper``'s (``jaxarm.paper.report.RULES``, and evosax's where it is
installed), among them preset A on the ring with its inertia falling from 1 to 0.4 instead of
0, under feasibility rules.

    .venv/bin/python benchmarks/rules_bench.py [--seeds 300] [--modes sampled,certified]
        [--parts rules,share] [--draws 100000] [--start-seeds 3000] [--scenarios a,b]
        [--methods "A-ring:feasibility,A-ring[inertia_end=0.4]:feasibility"] [--seed 0]
"""

from __future__ import annotations

import argparse

import jax
import numpy as np

import jaxarm
from jaxarm.choices import split_methods
from jaxarm.paper.report import rule_methods
from jaxarm.stats import wilson_interval


def rules_table(problem, n_restarts: int, labels: list[str] | None, seed: int) -> list[str]:
    methods = rule_methods()[0]
    if labels is not None:  # the death penalty always: the last column compares with it
        unknown = set(labels) - set(methods)
        if unknown:
            raise SystemExit(f"--methods: unknown {sorted(unknown)}")
        methods = [m for m in methods if m in set(labels) | {"A"}]
    result = jaxarm.escape_study(problem, methods, n_restarts=n_restarts, seed=seed, progress=False)
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
    parser.add_argument("--restarts", type=int, default=300)
    parser.add_argument("--modes", default="sampled,certified")
    parser.add_argument("--parts", default="rules,share",
                        help="comma-separated: rules (the rules table), share (feasible shares)")
    parser.add_argument("--draws", type=int, default=100_000,
                        help="uniform paths per feasible share")
    parser.add_argument("--start-seeds", type=int, default=3000,
                        help="initial swarms per measured iteration-0 escape")
    parser.add_argument("--methods", default=None,
                        help="comma-separated labels of the rules table's rows (default: all)")
    parser.add_argument("--seed", type=int, default=0, help="the studies' base seed (0)")
    parser.add_argument("--scenarios", default=None,
                        help="comma-separated scenario names (default: paper-case-1 and "
                             "death-trap for rules, every shipped one for share)")
    args = parser.parse_args()
    modes, parts = args.modes.split(","), args.parts.split(",")
    print(f"jax {jax.__version__} ({jax.default_backend()}), preset A, 20 particles\n")
    chosen = args.scenarios.split(",") if args.scenarios else None
    if "rules" in parts:
        labels = split_methods(args.methods) if args.methods else None
        rules_part(modes, args.restarts, chosen or ["paper-case-1", "death-trap"], labels, args.seed)
    if "share" in parts:
        share_part(modes, args.draws, args.start_seeds, chosen or jaxarm.available_scenarios())


def rules_part(modes: list[str], n_restarts: int, names: list[str], labels: list[str] | None,
               seed: int) -> None:
    print(f"{n_restarts} seeds from seed {seed}, 100 iterations\n")
    print("| scenario | check | rule | escape rate [95 % CI] | ends feasible | "
          "median / best fitness (feasible) | vs death penalty | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for mode in modes:
        for name in names:
            problem = jaxarm.load_scenario(name, collision=mode)
            for line in rules_table(problem, n_restarts, labels, seed):
                print(line, flush=True)


def share_part(modes: list[str], n_draws: int, n_restarts: int, names: list[str]) -> None:
    print(f"\nfeasible share from {n_draws} uniform paths; iteration-0 escape of {n_restarts} "
          "initial swarms\n")
    print("| scenario | check | free share [95 % CI] | start escape: predicted [95 % CI] | "
          "measured [95 % CI] | intervals overlap |")
    print("|---|---|---|---|---|---|")
    for mode in modes:
        for name in names:
            problem = jaxarm.load_scenario(name, collision=mode)
            share = jaxarm.feasible_fraction(problem, n_paths=n_draws)
            start = jaxarm.escape_study(problem, ["A"], n_restarts=n_restarts, n_iters=1,
                                        progress=False)["A"]
            hits = int(np.sum(start.outcome.escape_iter == 0))
            seen_low, seen_high = wilson_interval(hits, n_restarts)
            predicted, (low, high) = share.start_escape(20)
            overlap = "yes" if low <= seen_high and seen_low <= high else "no"
            print(f"| {name} | {mode} | {share.fraction:.3%} [{share.interval[0]:.3%}, "
                  f"{share.interval[1]:.3%}] | {predicted:.1%} [{low:.1%}, {high:.1%}] | "
                  f"{hits / n_restarts:.1%} [{seen_low:.1%}, {seen_high:.1%}] | {overlap} |",
                  flush=True)


if __name__ == "__main__":
    main()
