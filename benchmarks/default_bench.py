"""What ``solve(problem)`` with no options finds: a certified path in every call?

For every shipped scenario (or ``--scenarios``): ten default calls, ``solve(problem, seed=s)`` for
s = 0..9 (the certified check, the scenario's own settings), how many end certified
collision-free, their median and worst fitness, and the median against the best path that
``--restarts`` restarts of each of the default's methods (the ring and preset A, with feasibility
rules) find, together. Then the time of a warm default call on paper-case-1
(median of 5, after one call that compiles).

    .venv/bin/python benchmarks/default_bench.py [--seeds 10] [--restarts 200]
        [--scenarios a,b,...]

``--hard [--seeds 2]`` instead runs the default, time limit and all, on harder scenes
(``hard_scenes``): a margin on the shelf, a 5-link arm among 25 circles with a 1 cm margin
(built around a degree-8 path kept clear, so a free path exists), one where degree 6 has no
free path but degree 7 has (``s_bend``), and one with no path (the first link walled in
beside the base): how many calls end certified, at which degree, after
how many stages and how long, compiling included (each call after the first of a scene reuses
its programs).

``--cluttered [--scenes 50] [--counts 10,20,40] [--time-limit S]`` instead runs, on generated
cluttered scenes (the open-space arm among ``count`` random circles of radius 2-5 cm,
``jaxarm.clutter`` seeds 0..scenes-1, no corridor kept, so some have no path), the default
(seed 0) beside OMPL's RRTConnect with the same time limit (``peers.rrtconnect``: motions
checked every 0.002 of the joint space's extent, simplified when solved), and certifies
RRTConnect's paths with jaxarm: segment by segment, each a straight line in joint space, which
is the degree-6 path with no free coefficients between its ends (the same postures).
RRTConnect's jerk is that of its waypoints splined in arc length over r in [0, 1] with zero
velocity and acceleration at both ends, as jaxarm's paths start and stop (``peers.
waypoint_metrics(rest_to_rest=True)``), and in brackets with the clamped cubic spline that
``peers.py`` uses, whose acceleration jumps at the ends; "default smoother" counts the scenes
where the default's largest jerk is below the first.
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import numpy as np

import jaxarm
from jaxarm.choices import (DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS,
                            DEFAULT_TIME_LIMIT)
from jaxarm.escalation import at_degree
from jaxarm.io.scenario_files import available
from peers import path_metrics, rrtconnect, waypoint_metrics

REFERENCE_METHODS = tuple(f"{method}:{DEFAULT_CONSTRAINT}" for method in DEFAULT_METHODS)


def scenario_row(name: str, n_seeds: int, n_restarts: int) -> str:
    problem = jaxarm.load_scenario(name)
    calls = [jaxarm.solve(problem, seed=seed) for seed in range(n_seeds)]
    certified = [call.certified for call in calls]
    fitness = np.array([call.best_fitness for call in calls])
    reference = max(jaxarm.solve(problem, method, n_restarts=n_restarts, seed=0).best_fitness
                    for method in REFERENCE_METHODS)
    median = float(np.median(fitness))
    return (f"| {name} | {sum(certified)}/{n_seeds} | {median:.4f} | {fitness.min():.4f} | "
            f"{reference:.4f} | {median / reference - 1:+.1%} |")


def warm_call_seconds(repeats: int = 5) -> float:
    problem = jaxarm.load_scenario("paper-case-1")
    jaxarm.solve(problem)
    times = []
    for seed in range(repeats):
        began = time.perf_counter()
        jaxarm.solve(problem, seed=seed)
        times.append(time.perf_counter() - began)
    return statistics.median(times)


def s_bend() -> jaxarm.Problem:
    """Two posts, mirror images, and a base joint held to [-0.05, pi + 0.05] rad: no free path
    at degree 6, one at degree 7 (``S_BEND_PATH``).

    The base swings from 0 to pi. At degree 6 each joint leaves its quintic by one bump
    ``a6 r^3 (r - 1)^3`` (``jaxarm.model.path``), so the elbow, at 0 at both ends, keeps one
    sign all the way. The postures touching the right post form a band in joint space from the
    base's lower limit (elbow bent ahead) down across the straight arm: with the elbow never
    behind, the arm cannot get past it; the left post's band shuts out an elbow never ahead
    near the base's upper limit. The elbow must bend behind past the right post and ahead past
    the left one, an S. ``tests/test_escalation.py`` checks the bands on a grid of postures
    with shapely and certifies the path.
    """
    x, y = 72.0 * np.cos(0.4), 72.0 * np.sin(0.4)
    return jaxarm.Problem(
        arm=jaxarm.Arm((40.0, 40.0)), start=[0.0, 0.0], goal=[np.pi, 0.0], margin=1.0,
        joint_limits=[(-0.05, np.pi + 0.05), (-np.pi, np.pi)], name="s-bend",
        world=jaxarm.World(circles=[(x, y, 5.0), (-x, y, 5.0)]))


# a6, a7 of both joints: the elbow's S, -2.6 sin(2 pi r) 4 r (1 - r) by least squares, rounded
S_BEND_PATH = (0.0, 4027.0, 0.0, -1151.0)


def hard_scenes() -> dict:
    """The ``--hard`` scenes by name (module docstring)."""
    five = jaxarm.load_scenario("five-link-detour").replace(world=jaxarm.World(), margin=1.0,
                                                           degree=8)
    kept_clear = np.random.default_rng(0).uniform(-100.0, 100.0, five.n_free)
    return {
        "overhead-shelf, margin 2 cm": jaxarm.load_scenario("overhead-shelf", margin=2.0),
        **{f"5 links, 25 circles (clutter seed {seed}), margin 1 cm": jaxarm.clutter(
            five, 25, "circles", size=(3.0, 6.0), seed=seed, clear_path=kept_clear
        ).replace(degree=6) for seed in (0, 1)},
        "S-bend: no free path at degree 6, one at 7": s_bend(),
        "no path: the first link walled in": jaxarm.Problem(
            arm=jaxarm.Arm((30.0, 30.0, 20.0)), start=[0.0, 0.5, 0.5],
            goal=[np.pi, -0.5, -0.5], name="walled-in",
            world=jaxarm.World(boxes=[((-2.0, 4.0), (2.0, 10.0)),
                                      ((-2.0, -10.0), (2.0, -4.0))])),
    }


def hard_row(name: str, problem, n_seeds: int) -> str:
    calls = []
    for seed in range(n_seeds):
        began = time.perf_counter()
        result = jaxarm.solve(problem, seed=seed, progress=False)
        calls.append((result, time.perf_counter() - began))
    certified = sum(result.certified for result, _ in calls)
    degrees = sorted({result.degree for result, _ in calls if result.certified})
    stages = sorted({len(result.stages) for result, _ in calls})
    seconds = [elapsed for _, elapsed in calls]
    return (f"| {name} | {certified}/{n_seeds} | {', '.join(map(str, degrees)) or '-'} | "
            f"{', '.join(map(str, stages))} | {', '.join(f'{s:.0f}' for s in seconds)} |")


def cluttered_scenes(count: int, n_scenes: int) -> list:
    """The ``--cluttered`` scenes of one density (module docstring)."""
    base = jaxarm.load_scenario("open-space")
    return [jaxarm.clutter(base, count, "circles", size=(2.0, 5.0), seed=seed)
            for seed in range(n_scenes)]


def segments_certified(problem, waypoints) -> bool:
    """A waypoint path, each straight joint-space segment certified free as the degree-6 path
    with no free coefficients between its ends."""
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        try:
            segment = problem.replace(start=tuple(a), goal=tuple(b), degree=6)
        except ValueError:  # an end within the margin: not certified
            return False
        if not bool(jaxarm.certify(segment, np.zeros((1, segment.n_free))).free[0]):
            return False
    return True


def cluttered_scene(problem, time_limit: float) -> dict:
    """The default and RRTConnect on one scene: success, seconds, length and jerk of each."""
    began = time.perf_counter()
    result = jaxarm.solve(problem, seed=0, time_limit=time_limit, progress=False)
    row = {"jaxarm": result.certified, "jaxarm_s": time.perf_counter() - began,
           "degree": result.degree}
    if result.certified:
        length, jerk = path_metrics(at_degree(problem, result.degree), result.best_x)
        row.update(jaxarm_length=float(length), jaxarm_jerk=float(jerk))
    solved, first, _, waypoints = rrtconnect(problem, time_limit)
    row.update(ompl=solved, ompl_s=first)
    if solved:
        length, cubic_jerk = waypoint_metrics(waypoints)
        _, jerk = waypoint_metrics(waypoints, rest_to_rest=True)
        row.update(ompl_certified=segments_certified(problem, waypoints),
                   ompl_length=float(length), ompl_jerk=float(jerk),
                   ompl_cubic_jerk=float(cubic_jerk))
    return row


def cluttered_row(count: int, rows: list) -> str:
    """One density's line of the ``--cluttered`` table."""
    n = len(rows)
    ompl = [row for row in rows if row["ompl"]]
    both = [row for row in ompl if row["jaxarm"]]
    median = lambda key, subset: (f"{np.median([row[key] for row in subset]):.2f}"  # noqa: E731
                                  if subset else "-")
    smoother = sum(row["jaxarm_jerk"] < row["ompl_jerk"] for row in both)
    degrees = sorted({row["degree"] for row in rows if row["jaxarm"]})
    return (f"| {count} | {sum(row['jaxarm'] for row in rows)}/{n} "
            f"({', '.join(map(str, degrees)) or '-'}) | {len(ompl)}/{n} "
            f"({sum(row['ompl_certified'] for row in ompl)} certified) | "
            f"{len(both)}/{len(ompl)} | "
            f"{median('jaxarm_s', [r for r in rows if r['jaxarm']])} / "
            f"{median('ompl_s', ompl)} | "
            f"{median('jaxarm_length', both)} / {median('ompl_length', both)} | "
            f"{median('jaxarm_jerk', both)} / {median('ompl_jerk', both)} "
            f"({median('ompl_cubic_jerk', both)}) | "
            f"{smoother}/{len(both)} |")


def cluttered_main(counts: list, n_scenes: int, time_limit: float) -> None:
    from ompl import util

    util.RNG.setSeed(1)  # before any planner samples: the runs repeat
    print(f"{n_scenes} scenes per density: open-space + n circles of radius 2-5 cm "
          f"(jaxarm.clutter seeds 0..{n_scenes - 1}); the default (seed 0) and OMPL RRTConnect "
          f"+ simplify, {time_limit:g} s each; jax {jax.__version__} on "
          f"{jax.devices()[0].platform}\n")
    print("| circles | default certified (degrees) | RRTConnect solved | default certified "
          "where RRTConnect solved | median s: the default's call (compiling included on a "
          "density's first scene) / RRTConnect to its first solution | "
          "median joint-space length (rad), both solved | median max jerk (rad / r^3), both "
          "solved: default / RRTConnect at rest (cubic) | default smoother |")
    print("|---|---|---|---|---|---|---|---|")
    for count in counts:
        rows = [cluttered_scene(problem, time_limit)
                for problem in cluttered_scenes(count, n_scenes)]
        print(cluttered_row(count, rows), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None)
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--scenarios", default=",".join(available()))
    parser.add_argument("--hard", action="store_true")
    parser.add_argument("--cluttered", action="store_true")
    parser.add_argument("--scenes", type=int, default=50)
    parser.add_argument("--counts", default="10,20,40")
    parser.add_argument("--time-limit", type=float, default=DEFAULT_TIME_LIMIT)
    args = parser.parse_args()
    if args.cluttered:
        cluttered_main([int(c) for c in args.counts.split(",")], args.scenes, args.time_limit)
        return
    if args.hard:
        n_seeds = args.seeds or 2
        print(f"solve(problem, seed=s), s = 0..{n_seeds - 1}: the default, time limit "
              f"{DEFAULT_TIME_LIMIT:g} s; jax {jax.__version__} on "
              f"{jax.devices()[0].platform}\n")
        print("| scene | calls certified free | degree found | stages run | seconds per call |")
        print("|---|---|---|---|---|")
        for name, problem in hard_scenes().items():
            print(hard_row(name, problem, n_seeds), flush=True)
        return
    args.seeds = args.seeds or 10
    print(f"solve(problem, seed=s), s = 0..{args.seeds - 1}: {DEFAULT_RESTARTS} restarts each "
          f"of {' and '.join(DEFAULT_METHODS)} under {DEFAULT_CONSTRAINT} rules, certified check; "
          f"reference: "
          f"the best of {args.restarts} restarts each of {', '.join(REFERENCE_METHODS)}; "
          f"jax {jax.__version__} on {jax.devices()[0].platform}\n")
    print("| scenario | calls certified free | median fitness | worst fitness | reference best "
          "| median vs reference |")
    print("|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        print(scenario_row(name, args.seeds, args.restarts), flush=True)
    print(f"\nWarm default call on paper-case-1 (median of 5): {warm_call_seconds():.2f} s")


if __name__ == "__main__":
    main()
