"""OMPL's planar kinematic-chain benchmark, as jaxarm problems.

OMPL ships ``demos/KinematicChainBenchmark.cpp`` (Gipson and Moll): an N-link chain of total
length 1 (links 1/N) whose start angles are ``[0, pi/N, ..., pi/N]`` and goal ``[pi - 0.001,
0, ..., 0]``, inside a "horn" of 2 (N - 1) wall segments made by its
``createHornEnvironment(N, ln(N) / N)``: two polylines from (1/N, -eps) and (1/N, +eps), each
segment turning by a further pi/N, of lengths (1/N)(1 + pi eps) and (1/N)(1 - pi eps). Its
validity checker tests every pair of the chain's segments for intersection, and every segment
against every wall. Here the same, in cm (x 100), with self-collision on: the shipped
scenarios ``kinematic-chain-5``, ``-10`` and ``-20`` are written by

    python benchmarks/kinematic_chain.py --write

and ``tests/test_scenarios.py`` checks them against the demo's construction.
"""

from __future__ import annotations

import argparse
import math
import pathlib

import jaxarm
from jaxarm.io import scenario_files

SCALE = 100.0  # cm per unit of the demo
SIZES = (5, 10, 20)
HEADER = ("# OMPL's planar kinematic-chain benchmark (demos/KinematicChainBenchmark.cpp) in cm,\n"
          "# written by benchmarks/kinematic_chain.py --write: the chain, its start and goal, and\n"
          "# the horn of createHornEnvironment(N, ln(N) / N), scaled by 100.\n")
SCENARIOS = pathlib.Path(__file__).resolve().parents[1] / "jaxarm" / "scenarios"


def horn_segments(n_links: int) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """``createHornEnvironment(n_links, ln(n_links) / n_links)``'s segments, scaled: the lower
    polyline's then the upper one's, each as ((x0, y0), (x1, y1))."""
    eps = math.log(n_links) / n_links
    width = 1.0 / n_links
    segments = []
    for side, stretch in ((-1.0, 1.0 + math.pi * eps), (1.0, 1.0 - math.pi * eps)):
        x, y, theta, length = width, side * eps, 0.0, width * stretch
        for _ in range(n_links - 1):
            theta += math.pi / n_links
            x_next, y_next = x + math.cos(theta) * length, y + math.sin(theta) * length
            segments.append(((SCALE * x, SCALE * y), (SCALE * x_next, SCALE * y_next)))
            x, y = x_next, y_next
    return segments


def kinematic_chain(n_links: int) -> jaxarm.Problem:
    """The demo's problem for ``n_links`` links, in cm, self-collision on."""
    return jaxarm.Problem(
        arm=jaxarm.Arm((SCALE / n_links,) * n_links, self_collision=True),
        start=[0.0] + [math.pi / n_links] * (n_links - 1),
        goal=[math.pi - 0.001] + [0.0] * (n_links - 1),
        world=jaxarm.World(segments=horn_segments(n_links)),
        name=f"kinematic-chain-{n_links}",
        description=f"OMPL's KinematicChainBenchmark, {n_links} links of {SCALE / n_links:g} cm, "
                    "out of a horn of walls, self-collision on")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true",
                        help=f"write the scenarios kinematic-chain-{{{','.join(map(str, SIZES))}}}")
    args = parser.parse_args()
    for n_links in SIZES:
        problem = kinematic_chain(n_links)
        print(problem.summary())
        if args.write:
            path = SCENARIOS / f"{problem.name}.toml"
            path.write_text(HEADER + scenario_files.to_toml(problem), encoding="utf-8")
            print("wrote", path)


if __name__ == "__main__":
    main()
