"""Your own optimiser beside the PSO: a (1+8)-ES written to the public protocol
(``jaxarm.optim.custom``; no jaxarm internals imported) against preset A with feasibility rules,
both with 8 paths per iteration, in the same escape study: warm seconds per restart side by
side (medians of ``--repeats`` studies, in turns), and the escape rates.

    .venv/bin/python benchmarks/own_optimiser.py [--scenario death-trap] [--restarts 200]
        [--iters 100] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import jax.numpy as jnp

import jaxarm


class OnePlusLambdaES:
    """A (1+lambda)-ES: children by Gaussian steps around one parent, which the best child
    replaces when better (feasibility rules by hand); the step grows on success, else shrinks."""

    label = "(1+8)-ES"
    population = 8

    def init(self, key, low, high):
        parent = jax.random.uniform(key, low.shape, low.dtype, low, high)
        return {"parent": parent, "cost": jnp.asarray(jnp.inf, low.dtype),
                "sigma": jnp.mean(high - low) / 4}

    def ask(self, key, state):
        steps = jax.random.normal(key, (self.population,) + state["parent"].shape)
        return state["parent"] + state["sigma"] * steps, state

    def tell(self, state, x, evaluation):
        cost = jnp.where(evaluation.violation > 0, evaluation.violation, -evaluation.fitness)
        best = jnp.argmin(cost)
        better = cost[best] < state["cost"]
        return {"parent": jnp.where(better, x[best], state["parent"]),
                "cost": jnp.where(better, cost[best], state["cost"]),
                "sigma": state["sigma"] * jnp.where(better, 1.5, 0.9)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="death-trap")
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--iters", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    problem = jaxarm.load_scenario(args.scenario)
    methods = {"(1+8)-ES": OnePlusLambdaES(), "A:feasibility": "A:feasibility"}

    def study(method):
        return jaxarm.escape_study(problem, [method], n_restarts=args.restarts,
                                   n_iters=args.iters, n_particles=8, constraint="feasibility")

    rates = {label: study(method).methods[0].escape_rate()  # compiles each
             for label, method in methods.items()}
    times = {label: [] for label in methods}
    for _ in range(args.repeats):
        for label, method in methods.items():
            began = time.perf_counter()
            study(method)
            times[label].append(time.perf_counter() - began)
    per_restart = {label: statistics.median(t) / args.restarts for label, t in times.items()}
    print(f"{args.scenario} ({problem.collision} check), {args.restarts} restarts x "
          f"{args.iters} iterations, 8 paths per iteration, feasibility rules; median of "
          f"{args.repeats} warm studies in turns; jax {jax.__version__} on "
          f"{jax.devices()[0].platform}\n")
    print("| method | escape rate | ms per restart |")
    print("|---|---|---|")
    for label in methods:
        print(f"| {label} | {rates[label]:.0%} | {per_restart[label] * 1e3:.2f} |")
    ratio = per_restart["(1+8)-ES"] / per_restart["A:feasibility"]
    print(f"\n(1+8)-ES / PSO time per restart: {ratio:.2f}")


if __name__ == "__main__":
    main()
