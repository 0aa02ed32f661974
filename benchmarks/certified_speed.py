"""The certified search beside the sampled one: time, pieces per path, and nothing given up.

For every shipped scenario (or ``--scenarios``): ``solve(problem, METHOD, n_restarts=N, seed=0)``
under the paper's sampled check and under the certified check (the default), each compiled by
a first call and then timed ``--repeats`` times, the two in turn (median, wall clock; ``solve``
returns NumPy arrays, so the work is done when it returns). Beside the times: the certified
search's escape rate (certified check) with its 95 % Wilson interval and its best fitness; the
certified check's pieces per bisected path on the restarts' best paths (the near-optimal paths
a swarm ends on, where the check works hardest): median, p95 and max; and every certified-free
best path measured by the dense shapely oracle (``jaxarm.testing``, 20,001 times): the column
counts those it finds closer than the margin, which must be 0.

``--kernel``: the fitness kernel's throughput on 1e5 random paths of paper-case-1 (the init
range), sampled against certified, median of 7 warm calls each, in turn.

    .venv/bin/python benchmarks/certified_speed.py [--restarts 200] [--method A:feasibility]
        [--scenarios a,b,...] [--repeats 3] [--kernel]
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import numpy as np

import jaxarm
from jaxarm.checks import certified
from jaxarm.checks.evaluate import evaluate
from jaxarm.io.scenario_files import available
from jaxarm.stats import wilson_interval
from jaxarm.testing import dense_clearance

ORACLE_POINTS = 20_001


def timed(*functions, repeats: int):
    """Each function once to compile, then ``repeats`` rounds of one timed call of each in
    turn (so a slower phase of the machine falls on all of them): per function, (last result,
    median s)."""
    results = [function() for function in functions]
    times = [[] for _ in functions]
    for _ in range(repeats):
        for index, function in enumerate(functions):
            began = time.perf_counter()
            results[index] = function()
            times[index].append(time.perf_counter() - began)
    return [(result, statistics.median(spent)) for result, spent in zip(results, times)]


def pieces_per_path(problem: jaxarm.Problem, x: np.ndarray) -> np.ndarray:
    """The certified check's pieces for each path of x (n, n_free) that needed bisecting."""
    check = jax.jit(lambda arrays, x: certified.check(problem.spec, arrays, x))
    pieces = np.asarray(check(problem.arrays, np.asarray(x, np.float32)).pieces)
    return pieces[pieces > 0]


def scenario_row(name: str, method: str, n_restarts: int, repeats: int) -> tuple:
    """The scenario's table row, and its certified search's best paths (n_restarts, n_free)."""
    problem = jaxarm.load_scenario(name)
    sampled_problem = problem.replace(collision="sampled")
    (_, sampled_time), (result, certified_time) = timed(
        *(lambda problem=p: jaxarm.solve(problem, method, n_restarts=n_restarts, seed=0)
          for p in (sampled_problem, problem)), repeats=repeats)
    escaped = result.restarts.best_violation == 0
    low, high = wilson_interval(int(escaped.sum()), n_restarts)
    pieces = pieces_per_path(problem, result.restarts.best_x)
    spread = (f"{np.median(pieces):.0f} / {np.percentile(pieces, 95):.0f} / {pieces.max()}"
              if pieces.size else "none bisected")
    clearance = dense_clearance(problem, result.restarts.best_x[escaped], ORACLE_POINTS)
    too_close = int(np.sum(clearance < problem.margin))
    return (f"| {name} | {sampled_time:.2f} s | {certified_time:.2f} s | "
            f"{certified_time / sampled_time:.1f}x | {escaped.mean():.1%} "
            f"[{low:.1%}, {high:.1%}] | {result.best_fitness:.4f} | {spread} | "
            f"{too_close} of {int(escaped.sum())} |"), result.restarts.best_x


def kernel_rows(n_paths: int = 100_000, repeats: int = 7) -> list[str]:
    """Paths per second of the fitness kernel, sampled and certified, on random paths."""
    problem = jaxarm.load_scenario("paper-case-1")
    x = np.random.default_rng(0).uniform(problem.init_low, problem.init_high,
                                         (n_paths, problem.n_free)).astype(np.float32)
    rows, rates = [], {}
    modes = ("sampled", "certified")
    kernels = [jax.jit(lambda arrays, x, spec=problem.replace(collision=mode).spec:
                       evaluate(spec, arrays, x).fitness) for mode in modes]
    timings = timed(*(lambda kernel=kernel: kernel(problem.arrays, x).block_until_ready()
                      for kernel in kernels), repeats=repeats)
    for mode, (_, seconds) in zip(modes, timings):
        rates[mode] = n_paths / seconds
        rows.append(f"| {mode} | {seconds * 1e3:.0f} ms | {rates[mode] / 1e6:.2f} M paths/s |")
    rows.append(f"| certified / sampled | | {rates['certified'] / rates['sampled']:.0%} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=200)
    parser.add_argument("--method", default="A:feasibility")
    parser.add_argument("--scenarios", default=",".join(available()))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--kernel", action="store_true")
    parser.add_argument("--save-paths", metavar="FILE.npz",
                        help="also save each scenario's certified best paths (to measure them "
                             "with another version of the check)")
    args = parser.parse_args()
    saved = {}
    print(f"{args.method}, {args.restarts} restarts x 20 particles x 100 iterations, seed 0; "
          f"median of {args.repeats} warm calls each, sampled and certified in turn; "
          f"jax {jax.__version__} on {jax.devices()[0].platform}\n")
    print("| scenario | sampled search | certified search | ratio | escape (certified) [95 %] "
          "| best fitness | pieces per bisected best path (median / p95 / max) | "
          "oracle: closer than the margin |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        row, saved[name] = scenario_row(name, args.method, args.restarts, args.repeats)
        print(row, flush=True)
    if args.save_paths:
        np.savez(args.save_paths, **saved)
    if args.kernel:
        print("\n| fitness kernel, paper-case-1, 1e5 random paths | median | throughput |")
        print("|---|---|---|")
        print("\n".join(kernel_rows()))


if __name__ == "__main__":
    main()
