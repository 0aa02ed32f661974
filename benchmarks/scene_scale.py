"""Scenes at scale: what a check and a search cost as the obstacles grow, from 4 to 1,000.

Scenes: ``jaxarm.clutter`` on open-space (the 3-link arm; its start, goal and the path with
no free coefficients kept clear), seed 0,
circles (4 to 1,000) and triangles (4 to 250) of circumradius 0.5 to 3 cm, scaled by
``sqrt(64 / count)`` past 64 obstacles so that they cover about the same share of the reach
(about 4 %); and the shipped map scene (``--map``, the scenario ``workcell-map``).

Each row runs in a fresh process with no persistent cache (``JAXARM_CACHE_DIR=off``), under
each check: ``first`` is the first ``jaxarm.fitness`` call on 20,000 random paths (the
problem's init range, seed 0), compiling included; ``warm`` the median of 3 more (paths/s);
``memory`` the process's peak resident set (which includes JAX itself). With ``--search``,
also ``solve(problem, "A:feasibility", n_restarts=50)``: its first call and one warm call,
how many of the restarts it ran escaped (it stops at a stage's first chunk with a certified
path), and whether its path is certified.
``--before`` turns the broad phase off (every slot written out in one program, as before it
existed), with ``--timeout`` seconds per row.

    .venv/bin/python benchmarks/scene_scale.py [--map] [--search] [--before] [--quick]
        [--circles 16,1000] [--triangles 250] [--checks certified]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

CIRCLES = (4, 16, 64, 128, 256, 1000)
TRIANGLES = (4, 16, 32, 64, 250)
PATHS = 20_000


def scene(kind: str, count: int):
    """The benchmark's scene: ``count`` obstacles of ``kind`` on open-space, or the map."""
    import jaxarm

    if kind == "map":
        return jaxarm.load_scenario("workcell-map")
    scale = min(1.0, (64 / count) ** 0.5)
    return jaxarm.clutter(jaxarm.load_scenario("open-space"), count, kind,
                          size=(0.5 * scale, 3.0 * scale), seed=0, clear_path=0)


def measure(kind: str, count: int, check: str, search: bool, before: bool) -> dict:
    """One row, in this process (the child)."""
    import resource
    import statistics

    import jax
    import numpy as np

    import jaxarm
    from jaxarm.model import nearby

    if before:
        nearby.BROAD_PHASE_WORK = 10**9
    problem = scene(kind, count).replace(collision=check)
    low, high = problem.bounds()
    x = np.random.default_rng(0).uniform(low, high, (PATHS, problem.n_free)).astype(np.float32)
    began = time.perf_counter()
    fitness = np.asarray(jaxarm.fitness(problem, x))
    row = {"first": time.perf_counter() - began, "free": float(np.mean(fitness > 0))}
    spent = []
    for _ in range(3):
        began = time.perf_counter()
        jax.block_until_ready(jaxarm.fitness(problem, x))
        spent.append(time.perf_counter() - began)
    row["paths_per_s"] = PATHS / statistics.median(spent)
    if search:
        began = time.perf_counter()
        jaxarm.solve(problem, "A:feasibility", n_restarts=50, seed=0)
        row["search_first"] = time.perf_counter() - began
        began = time.perf_counter()
        result = jaxarm.solve(problem, "A:feasibility", n_restarts=50, seed=0)
        row["search_warm"] = time.perf_counter() - began
        row["escapes"] = int(np.sum(result.restarts.feasible))
        row["restarts"] = len(result.restarts.feasible)  # fewer once a stage certifies
        row["certified"] = bool(result.certified)
    row["memory_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    row["obstacles"] = problem.world.n_obstacles
    return row


def run_row(kind: str, count: int, check: str, args) -> dict | None:
    """One row in a fresh process; None when it fails or runs out of time."""
    command = [sys.executable, __file__, "--child", kind, str(count), check]
    command += ["--search"] * args.search + ["--before"] * args.before
    environment = dict(os.environ, JAXARM_CACHE_DIR="off")
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=args.timeout,
                              env=environment)
    except subprocess.TimeoutExpired:
        return None
    if done.returncode:
        print(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode,
              file=sys.stderr)
        return None
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--search", action="store_true", help="time solve too")
    parser.add_argument("--before", action="store_true", help="without the broad phase")
    parser.add_argument("--quick", action="store_true", help="a few small scenes")
    parser.add_argument("--map", action="store_true", help="the map scene too")
    parser.add_argument("--timeout", type=float, default=900.0, help="s per row")
    parser.add_argument("--circles", help="comma-separated counts (default: 4 to 1000)")
    parser.add_argument("--triangles", help="comma-separated counts (default: 4 to 250)")
    parser.add_argument("--checks", default="sampled,certified", help="comma-separated")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, count, check = args.child
        print(json.dumps(measure(kind, int(count), check, args.search, args.before)))
        return
    counts = {kind: ([int(n) for n in given.split(",")] if given else (4, 64) if args.quick
                     else default) for kind, given, default in (
                         ("circles", args.circles, CIRCLES),
                         ("triangles", args.triangles, TRIANGLES))}
    scenes = ([(kind, n) for kind in ("circles", "triangles") for n in counts[kind]]
              + [("map", 0)] * args.map)
    header = ("| scene | obstacles | check | paths/s (warm) | first call (s) | peak memory (GB) |"
              + (" search first / warm (s) | escapes / restarts run | certified |"
                 if args.search else ""))
    print(header)
    print("|" + "---|" * (header.count("|") - 1))
    for kind, count in scenes:
        for check in args.checks.split(","):
            row = run_row(kind, count, check, args)
            name = "map" if kind == "map" else f"{count} {kind}"
            if row is None:
                print(f"| {name} | | {check} | | over {args.timeout:.0f} s or failed | | "
                      + ("| | |" if args.search else ""), flush=True)
                continue
            line = (f"| {name} | {row['obstacles']} | {check} | {row['paths_per_s'] / 1e3:,.1f} k "
                    f"| {row['first']:.2f} | {row['memory_gb']:.2f} |")
            if args.search:
                line += (f" {row['search_first']:.1f} / {row['search_warm']:.2f} | "
                         f"{row['escapes']} / {row['restarts']} | {row['certified']} |")
            print(line, flush=True)


if __name__ == "__main__":
    main()
