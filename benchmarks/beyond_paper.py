"""Degree 6 vs 7 vs 8 and PSO vs PSO + refine on the paper's cases; prints a markdown table.

The function behind ``jaxarm reproduce-paper``'s section, here under the paper's sampled
check (the report's section searches under the certified one), the three cases at shared
obstacle capacities (``jaxarm.share_capacities``).

    .venv/bin/python benchmarks/beyond_paper.py [--restarts 100]
"""

import argparse
import platform

import jax

import jaxarm
from jaxarm.optim.restarts import N_ITERS, N_PARTICLES
from jaxarm.paper.report import compare_degrees_and_refine, degree_refine_table


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--restarts", type=int, default=100)
    args = parser.parse_args()
    problems = jaxarm.share_capacities(
        [jaxarm.load_scenario(f"paper-case-{i}", collision="sampled") for i in (1, 2, 3)])
    rows = compare_degrees_and_refine(problems, n_restarts=args.restarts)
    print(f"jax {jax.__version__} on {jax.default_backend()}, {platform.processor()}, "
          f"{args.restarts} restarts x {N_PARTICLES} particles x {N_ITERS} iterations, preset A")
    print("\n".join(degree_refine_table(rows)))


if __name__ == "__main__":
    main()
