"""jaxarm against the tools people use, on the same scenarios and the same geometry.

- jaxarm PSO (preset A) with the death penalty and with feasibility rules;
- pyswarms GlobalBestPSO and evosax PSO (20 particles, 100 iterations, same initial range),
  driving jaxarm's fitness: the death penalty (cost = -fitness) and a penalty (cost =
  -fitness + violation, which ranks colliding paths by penetration like feasibility rules);
- pycma's CMA-ES under its augmented-Lagrangian constraint handling
  (``cma.ConstrainedFitnessAL`` with ``find_feasible_first=True``: only the violation is
  minimised until a feasible path is found, then the travelling distance subject to
  violation <= 0), population 20, 101 generations (the PSO's 20 x (100 + 1) evaluations), started
  at a uniform draw from the initial range with sigma = a quarter of its width;
- OMPL RRTConnect with path simplification, in joint space, with a validity checker on the same
  link/obstacle geometry (NumPy, per posture).

Metrics per method: success rate (a collision-free path at the end) with a 95 % Wilson interval,
wall time per run, median time to the first feasible path, median joint-space path length
(integral of |dtheta/dr|), median maximum jerk max |d^3 theta / d r^3| with every path
parameterised over r in [0, 1] (OMPL's waypoints by a clamped cubic spline in arc length).
Requires ``pip install -e '.[bench]'``.

    .venv/bin/python benchmarks/peers.py [--seeds 30] [--scenarios paper-case-1,...]

With ``--kinematic-chain 5,10,20``: OMPL's kinematic-chain benchmark instead
(``benchmarks/kinematic_chain.py``), OMPL's RRTConnect, KPIECE1, STRIDE and PRM beside jaxarm's
default search and fixed higher degrees, ``--runs`` runs of ``--budget`` seconds each.
"""

from __future__ import annotations

import argparse
import atexit
import json
import os
import tempfile
import time

import jax
import jax.numpy as jnp
import numpy as np
from scipy.interpolate import CubicSpline, make_interp_spline

import jaxarm
from jaxarm.checks.evaluate import evaluate
from jaxarm.study import wilson_interval

N_PARTICLES, N_ITERS = 20, 100


def path_metrics(problem, x):
    """Joint-space length and max jerk of polynomial paths x (..., n_free) over r in [0, 1],
    each of shape (...)."""
    r = np.linspace(0.0, 1.0, 2001)
    velocity = np.asarray(jaxarm.joint_path(problem, x, r, order=1), np.float64)
    jerk = np.asarray(jaxarm.joint_path(problem, x, r, order=3), np.float64)
    length = np.trapezoid(np.linalg.norm(velocity, axis=-1), r, axis=-1)
    return length, np.abs(jerk).max(axis=(-2, -1))


def waypoint_metrics(waypoints, rest_to_rest: bool = False):
    """Joint-space length and max jerk of a waypoint path, splined over r in [0, 1] in arc
    length: a clamped cubic spline (zero velocity at the ends; the acceleration jumps there),
    or with ``rest_to_rest`` a quintic one with zero velocity and acceleration at both ends, as
    jaxarm's paths have."""
    steps = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    length = steps.sum()
    r = np.concatenate([[0.0], np.cumsum(steps)]) / max(length, 1e-12)
    if rest_to_rest:
        at_rest = [(1, np.zeros(waypoints.shape[1])), (2, np.zeros(waypoints.shape[1]))]
        spline = make_interp_spline(r, waypoints, k=5, bc_type=(at_rest, at_rest))
    else:
        spline = CubicSpline(r, waypoints, bc_type="clamped")
    jerk = spline(np.linspace(0.0, 1.0, 2001), 3)
    return length, np.abs(jerk).max()


class Row(dict):
    pass


def summarise(name, successes, seconds, first_times, lengths, jerks):
    successes = np.asarray(successes, bool)
    low, high = wilson_interval(int(successes.sum()), len(successes))
    median = lambda v: float(np.median(v)) if len(v) else float("nan")  # noqa: E731
    return Row(method=name, success=successes.mean(), low=low, high=high,
               seconds=float(np.mean(seconds)), first=median(first_times),
               length=median(lengths), jerk=median(jerks))


def run_jaxarm(problem, constraint, n_restarts):
    jaxarm.solve(problem, "A", n_restarts=n_restarts, constraint=constraint)  # compile
    began = time.perf_counter()
    result = jaxarm.solve(problem, "A", n_restarts=n_restarts, constraint=constraint, seed=1)
    per_run = (time.perf_counter() - began) / n_restarts
    jaxarm.solve(problem, "A", n_restarts=1, constraint=constraint)  # compile one restart
    began = time.perf_counter()
    jaxarm.solve(problem, "A", n_restarts=1, constraint=constraint, seed=1)
    single = time.perf_counter() - began
    ok = result.restarts.best_violation == 0
    escape = result.restarts.escape_iter[ok]
    metrics = [path_metrics(problem, x) for x in result.restarts.best_x[ok]]
    return summarise(f"jaxarm PSO A, {constraint}", ok, [per_run],
                     single * (escape + 1) / (N_ITERS + 1),
                     [m[0] for m in metrics], [m[1] for m in metrics])


compiled_evaluate = jax.jit(evaluate, static_argnums=0)


def _cost_fn(problem, penalty):
    def cost(x):
        evaluation = compiled_evaluate(problem.spec, problem.arrays, jnp.asarray(x, jnp.float32))
        value = -np.asarray(evaluation.fitness, np.float64)
        return value + np.asarray(evaluation.violation) if penalty else value
    return cost


def _import_pyswarms():
    """pyswarms, with its logging kept quiet: by default every optimizer it builds configures
    logging with a file handler that creates ``report.log`` in the working directory. Its
    ``LOG_CFG`` variable names a logging configuration (YAML, which JSON is) to use instead."""
    if "LOG_CFG" not in os.environ:
        quiet = {"version": 1, "disable_existing_loggers": False,
                 "handlers": {"none": {"class": "logging.NullHandler"}},
                 "loggers": {"pyswarms": {"handlers": ["none"], "propagate": False}}}
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as config:
            json.dump(quiet, config)
        atexit.register(os.remove, config.name)
        os.environ["LOG_CFG"] = config.name
    import pyswarms

    return pyswarms


def run_pyswarms(problem, penalty, n_restarts):
    pyswarms = _import_pyswarms()

    low, high = problem.bounds()
    cost = _cost_fn(problem, penalty)
    successes, seconds, firsts, lengths, jerks = [], [], [], [], []
    for seed in range(n_restarts):
        rng = np.random.default_rng(seed)
        np.random.seed(seed)
        init = rng.uniform(low, high, (N_PARTICLES, problem.n_free))
        optimizer = pyswarms.single.GlobalBestPSO(
            N_PARTICLES, problem.n_free, options={"c1": 1.5, "c2": 1.5, "w": 0.7}, init_pos=init)
        began = time.perf_counter()
        _, best = optimizer.optimize(cost, iters=N_ITERS, verbose=False)
        elapsed = time.perf_counter() - began
        ok = not bool(jaxarm.collides(problem, best))
        successes.append(ok)
        seconds.append(elapsed)
        if ok:
            feasible_costs = np.asarray(optimizer.cost_history) < 0
            first = int(np.argmax(feasible_costs)) if feasible_costs.any() else N_ITERS
            firsts.append(elapsed * (first + 1) / N_ITERS)
            length, jerk = path_metrics(problem, best)
            lengths.append(length)
            jerks.append(jerk)
    return summarise(f"pyswarms GlobalBestPSO, {'penalty' if penalty else 'death'}", successes,
                     seconds, firsts, lengths, jerks)


def run_evosax(problem, penalty, n_restarts):
    from evosax.algorithms import PSO

    low, high = (jnp.asarray(b, jnp.float32) for b in problem.bounds())
    strategy = PSO(population_size=N_PARTICLES, solution=jnp.zeros(problem.n_free))
    params = strategy.default_params.replace(inertia_coeff=0.7, cognitive_coeff=1.5,
                                             social_coeff=1.5)
    spec, arrays = problem.spec, problem.arrays

    def cost(x):
        evaluation = evaluate(spec, arrays, x)
        return -evaluation.fitness + (evaluation.violation if penalty else 0.0)

    def one_seed(key):
        init_key, key = jax.random.split(key)
        population = low + (high - low) * jax.random.uniform(init_key, (N_PARTICLES, low.size))
        state = strategy.init(key, population, cost(population), params)

        def body(state, key):
            ask_key, tell_key = jax.random.split(key)
            population, state = strategy.ask(ask_key, state, params)
            state, _ = strategy.tell(tell_key, population, cost(population), state, params)
            return state, state.best_fitness

        state, best_costs = jax.lax.scan(body, state, jax.random.split(key, N_ITERS))
        return state.best_solution, best_costs

    run = jax.jit(jax.vmap(one_seed))
    keys = jax.random.split(jax.random.key(0), n_restarts)
    jax.block_until_ready(run(keys))  # compile
    began = time.perf_counter()
    best_x, best_costs = jax.block_until_ready(run(keys))
    per_run = (time.perf_counter() - began) / n_restarts
    best_x, best_costs = np.asarray(best_x), np.asarray(best_costs)
    ok = ~np.asarray(jaxarm.collides(problem, best_x))
    firsts = [per_run * (int(np.argmax(c < 0)) + 1) / N_ITERS for c in best_costs[ok]]
    metrics = [path_metrics(problem, x) for x in best_x[ok]]
    return summarise(f"evosax PSO, {'penalty' if penalty else 'death'}", ok, [per_run], firsts,
                     [m[0] for m in metrics], [m[1] for m in metrics])


def run_pycma(problem, n_restarts):
    import cma

    low, high = problem.bounds()
    successes, seconds, firsts, lengths, jerks = [], [], [], [], []
    for seed in range(n_restarts):
        measured = {}  # ConstrainedFitnessAL asks for f and g one path at a time

        def distance(x):
            return measured[x.tobytes()][0]

        def violation(x):
            return [measured[x.tobytes()][1]]

        x0 = np.random.default_rng(seed).uniform(low, high)
        es = cma.CMAEvolutionStrategy(x0, float(np.mean(high - low)) / 4, {
            "popsize": N_PARTICLES, "seed": seed + 1, "verbose": -9, "tolfun": 0, "tolx": 0,
            "tolfunhist": 0, "tolstagnation": 0, "verb_log": 0})  # no outcmaes/ files
        # No archives: they only track non-dominated solutions (and need moarchiving, which
        # was not installed when the figures in RESULTS.md were measured).
        objective = cma.ConstrainedFitnessAL(distance, violation, find_feasible_first=True,
                                             logging=0, archives=False)
        first, began = None, time.perf_counter()
        for generation in range(N_ITERS + 1):
            population = np.asarray(es.ask())
            evaluation = compiled_evaluate(problem.spec, problem.arrays,
                                           jnp.asarray(population, jnp.float32))
            for x, d, v in zip(population, np.asarray(evaluation.distance, np.float64),
                               np.asarray(evaluation.violation, np.float64)):
                measured[x.tobytes()] = (d, v)
            es.tell(population, [objective(x) for x in population])
            objective.update(es)
            if first is None and np.any(np.asarray(evaluation.violation) == 0):
                first = generation
            if es.stop():
                break
        elapsed = time.perf_counter() - began
        best = objective.best_feas.x
        ok = best is not None and not bool(jaxarm.collides(problem, best))
        successes.append(ok)
        seconds.append(elapsed)
        if ok:
            firsts.append(elapsed * (first + 1) / (generation + 1))
            length, jerk = path_metrics(problem, best)
            lengths.append(length)
            jerks.append(jerk)
    return summarise("pycma CMA-ES, augmented Lagrangian", successes, seconds, firsts, lengths,
                     jerks)


def posture_checker(problem):
    """A fast NumPy check of one posture against the problem's obstacles, kept ``margin`` away
    (polygons by separating axes: a posture within the margin of a corner may be refused), and
    for an arm that checks self-collision, every two links that are not neighbours too
    (``self_collision.posture_pair_separations``)."""
    from jaxarm.model.self_collision import posture_pair_separations

    arrays = problem.arrays
    margin = problem.margin
    world = arrays.world
    circles = world.circles[world.circle_valid]
    polygons = [(world.normals[p][world.edge_valid[p]], world.extent_low[p][world.edge_valid[p]],
                 world.extent_high[p][world.edge_valid[p]], world.vertices[p])
                for p in np.nonzero(world.polygon_valid)[0]]

    def free(q):
        absolute = np.cumsum(q)
        ends = np.cumsum(arrays.lengths[:, None]
                         * np.stack([np.cos(absolute), np.sin(absolute)], -1), axis=0)
        starts = np.vstack([[0.0, 0.0], ends[:-1]])
        d = ends - starts
        for cx, cy, radius in circles:
            t = np.clip(((cx - starts[:, 0]) * d[:, 0] + (cy - starts[:, 1]) * d[:, 1])
                        / (d**2).sum(1), 0, 1)
            if np.any(np.hypot(starts[:, 0] + t * d[:, 0] - cx,
                               starts[:, 1] + t * d[:, 1] - cy) < radius + margin):
                return False
        normal = np.stack([-d[:, 1], d[:, 0]], -1) / np.linalg.norm(d, axis=1, keepdims=True)
        offset = (normal * starts).sum(1)
        for normals, low, high, vertices in polygons:
            a, b = starts @ normals.T, ends @ normals.T
            gap = np.maximum(np.minimum(a, b) - high, low - np.maximum(a, b)).max(1)
            along = normal @ vertices.T
            gap = np.maximum(gap, np.maximum(along.min(1) - offset, offset - along.max(1)))
            if np.any(gap < margin):
                return False
        return not (problem.arm.self_collision
                    and np.any(posture_pair_separations(arrays.lengths, q) < margin))

    return free


def rrtconnect(problem, budget: float, resolution: float = 0.002):
    """One OMPL RRTConnect run (``ompl_plan``)."""
    return ompl_plan(problem, budget, resolution, "RRTConnect")


def ompl_plan(problem, budget: float, resolution: float = 0.002, planner: str = "RRTConnect"):
    """One run of an OMPL planner (a class of ``ompl.geometric``: RRTConnect, KPIECE1, STRIDE,
    PRM, ...) in joint space (each joint within pi of its start and goal angles, a real vector
    space with its default projection; motions checked every ``resolution`` of the space's
    extent), simplified when solved.

    Returns:
      (solved, seconds to the first solution, seconds in all, waypoints (n, n_joints) or None).
    """
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_ERROR)
    n = problem.n_joints
    start, goal = np.asarray(problem.start), np.asarray(problem.goal)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for j in range(n):
        bounds.setLow(j, min(start[j], goal[j]) - np.pi)
        bounds.setHigh(j, max(start[j], goal[j]) + np.pi)
    space.setBounds(bounds)
    free = posture_checker(problem)
    setup = og.SimpleSetup(space)
    setup.setStateValidityChecker(lambda s: free(np.array([s[j] for j in range(n)])))
    setup.getSpaceInformation().setStateValidityCheckingResolution(resolution)
    s, g = space.allocState(), space.allocState()
    for j in range(n):
        s[j], g[j] = float(start[j]), float(goal[j])
    setup.setStartAndGoalStates(s, g)
    setup.setPlanner(getattr(og, planner)(setup.getSpaceInformation()))
    began = time.perf_counter()
    solved = setup.solve(budget)
    first = time.perf_counter() - began
    ok = bool(solved) and setup.haveExactSolutionPath()
    if not ok:
        return False, first, time.perf_counter() - began, None
    setup.simplifySolution()
    found = setup.getSolutionPath()
    waypoints = np.array([[found.getState(i)[j] for j in range(n)]
                          for i in range(found.getStateCount())])
    return True, first, time.perf_counter() - began, waypoints


def run_ompl(problem, n_restarts, budget=1.0):
    successes, seconds, firsts, lengths, jerks = [], [], [], [], []
    for _ in range(n_restarts):  # one RNG stream, seeded once in main(): runs are repeatable
        ok, first, elapsed, waypoints = rrtconnect(problem, budget)
        seconds.append(elapsed)
        successes.append(ok)
        if ok:
            firsts.append(first)
            length, jerk = waypoint_metrics(waypoints)
            lengths.append(length)
            jerks.append(jerk)
    return summarise("OMPL RRTConnect + simplify", successes, seconds, firsts, lengths, jerks)


OMPL_PLANNERS = ("RRTConnect", "KPIECE1", "BKPIECE1", "STRIDE", "PRM")  # those OMPL's Python
#   bindings hold run (the ompl 2.0.1 wheel has no STRIDE; the table says which were missing)


def kinematic_chain(n_links: int, runs: int, budget: float, degrees: list):
    """OMPL's kinematic-chain benchmark (``kinematic-chain-N``): OMPL's planners, jaxarm's
    default search and jaxarm PSO A with feasibility rules at fixed higher degrees, each with
    ``budget`` seconds per run; rows of success rate, median seconds to the first solution,
    median joint-space length, and for jaxarm how many solutions are certified, yielded as
    each method ends."""
    from ompl import geometric

    problem = jaxarm.load_scenario(f"kinematic-chain-{n_links}")
    for planner in OMPL_PLANNERS:
        if not hasattr(geometric, planner):
            print(f"(OMPL {planner}: not in this ompl's Python bindings)")
            continue
        found = [ompl_plan(problem, budget, planner=planner) for _ in range(runs)]
        lengths = [waypoint_metrics(w)[0] for ok, _, _, w in found if ok]
        yield _chain_row(f"OMPL {planner}", [f[0] for f in found],
                         [f[1] for f in found if f[0]], lengths, None)
    searches = [("jaxarm default", problem, {})] + [
        (f"jaxarm A:feasibility, degree {d}", problem.replace(degree=d),
         dict(method="A:feasibility", n_restarts=256)) for d in degrees]
    for name, scene, settings in searches:
        kwargs = dict(time_limit=budget, progress=False) if not settings else settings
        began = time.perf_counter()
        jaxarm.solve(scene, **kwargs)  # compiles
        first_call = time.perf_counter() - began
        results, seconds = [], []
        for seed in range(1, runs + 1):
            began = time.perf_counter()
            results.append(jaxarm.solve(scene, seed=seed, **kwargs))
            seconds.append(time.perf_counter() - began)
        solved = [r.feasible for r in results]
        lengths = [path_metrics(scene, r.best_x)[0] for r in results if r.feasible]
        row = _chain_row(name, solved, [t for t, ok in zip(seconds, solved) if ok], lengths,
                         sum(bool(r.certified) for r in results))
        yield row | {"first_call": first_call}


def _chain_row(name, solved, seconds, lengths, certified):
    solved = np.asarray(solved, bool)
    low, high = wilson_interval(int(solved.sum()), len(solved))
    median = lambda v: float(np.median(v)) if len(v) else float("nan")  # noqa: E731
    return Row(method=name, success=solved.mean(), low=low, high=high, first=median(seconds),
               length=median(lengths), certified=certified, runs=len(solved))


def main_kinematic_chain(args) -> None:
    from ompl import util

    util.RNG.setSeed(1)
    print(f"jax {jax.__version__} ({jax.default_backend()}), OMPL's kinematic-chain scenes, "
          f"{args.runs} runs per method, {args.budget:g} s each")
    for n_links in (int(n) for n in args.kinematic_chain.split(",")):
        print(f"\n### kinematic-chain-{n_links}\n")
        print("| method | solved [95 % CI] | median s to a solution | median joint-space length "
              "(rad) | certified | first call, compiling (s) |")
        print("|---|---|---|---|---|---|")
        for row in kinematic_chain(n_links, args.runs, args.budget, args.degrees):
            certified = "–" if row["certified"] is None else f"{row['certified']}/{row['runs']}"
            first_call = f"{row['first_call']:.1f}" if "first_call" in row else "–"
            print(f"| {row['method']} | {row['success']:.0%} [{row['low']:.0%}, "
                  f"{row['high']:.0%}] | {row['first']:.2f} | {row['length']:.2f} | "
                  f"{certified} | {first_call} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinematic-chain", metavar="SIZES",
                        help="run OMPL's kinematic-chain benchmark instead, on these chain "
                             "lengths (comma-separated, from 5, 10, 20)")
    parser.add_argument("--runs", type=int, default=5, help="runs per method (kinematic chain)")
    parser.add_argument("--budget", type=float, default=10.0,
                        help="seconds per run (kinematic chain)")
    parser.add_argument("--degrees", type=lambda v: [int(d) for d in v.split(",") if d],
                        default=[10, 14],
                        help="jaxarm's fixed degrees (kinematic chain; '' for none)")
    parser.add_argument("--restarts", type=int, default=30)
    parser.add_argument("--scenarios", default="paper-case-1,paper-case-2,narrow-gap,death-trap")
    parser.add_argument("--peers", default=",".join(PEERS),
                        help=f"comma-separated, from {','.join(PEERS)} (all)")
    args = parser.parse_args()
    if args.kinematic_chain:
        main_kinematic_chain(args)
        return
    peers = args.peers.split(",")
    unknown = sorted(set(peers) - set(PEERS))
    if unknown:
        parser.error(f"--peers: unknown {unknown}, choose from {list(PEERS)}")
    if "ompl" in peers:
        from ompl import util

        util.RNG.setSeed(1)  # before any planner samples
    print(f"jax {jax.__version__} ({jax.default_backend()}), {args.restarts} seeds per method, "
          f"{N_PARTICLES} particles x {N_ITERS} iterations for the PSOs, 1 s budget for OMPL")
    for name in args.scenarios.split(","):
        problem = jaxarm.load_scenario(name)
        print(f"\n### {name} ({problem.collision} check)\n")
        rows = [run_jaxarm(problem, "death", args.restarts),
                run_jaxarm(problem, "feasibility", args.restarts)]
        for peer in peers:
            rows += PEERS[peer](problem, args.restarts)
        print("| method | success [95 % CI] | s per run | median s to first feasible | "
              "median joint-space length (rad) | median max jerk (rad / r^3) |")
        print("|---|---|---|---|---|---|")
        for row in rows:
            print(f"| {row['method']} | {row['success']:.0%} [{row['low']:.0%}, "
                  f"{row['high']:.0%}] | {row['seconds']:.4f} | {row['first']:.4f} | "
                  f"{row['length']:.3f} | {row['jerk']:.0f} |")


PEERS = {
    "pyswarms": lambda problem, n: [run_pyswarms(problem, False, n),
                                    run_pyswarms(problem, True, n)],
    "evosax": lambda problem, n: [run_evosax(problem, False, n), run_evosax(problem, True, n)],
    "pycma": lambda problem, n: [run_pycma(problem, n)],
    "ompl": lambda problem, n: [run_ompl(problem, n)],
}


if __name__ == "__main__":
    main()
