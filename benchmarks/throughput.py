"""Fitness-kernel throughput: jaxarm (sampled and certified) against vectorised NumPy.

Paths per second for ``jaxarm.fitness``'s kernel on paper-case-1 (3 links, 101 samples,
float32), side by side with a NumPy implementation of the same maths written here and checked
to agree. Also the work per path (arithmetic, comparisons and selects in the jaxpr, loops
unrolled) against the machine's measured float32 matmul peak.

    .venv/bin/python benchmarks/throughput.py [--max-batch 1000000] [--repeats 7]

``--evaluate`` instead times ``jaxarm.evaluate`` (fitness, violation and distance in one pass)
beside ``jaxarm.fitness`` alone and the three public functions called one after the other, on
20,000 random paths of paper-case-1, sampled and certified, called from the host and inside a
caller's ``jax.jit``, in turns in the same run.

``--self-collision`` instead times ``jaxarm.fitness`` on 20,000 random paths with and without
self-collision (``Arm(self_collision=True)``), sampled and certified, on paper-case-1 (3 links),
five-link-detour (5 links) and kinematic-chain-10 (10 links): the first call (compiling; the
persistent cache is off from Python) once each, then warm calls in turns in the same run.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxarm
import jaxarm.model.self_collision
from jaxarm.checks.evaluate import evaluate
from jaxarm.model import path


def numpy_fitness(problem: jaxarm.Problem, x: np.ndarray) -> np.ndarray:
    """Paper eq. 17 in vectorised NumPy (float64), the same model as jaxarm's sampled mode."""
    arrays = problem.arrays
    r = np.linspace(0.0, 1.0, problem.n_samples)
    free = x.reshape(len(x), -1, problem.n_joints)  # (B, m, J)
    delta = arrays.goal - arrays.start

    def angles(order):
        basis = path.basis_values(problem.degree, r, order)  # (S, m + 1)
        theta = basis[None, :, :1] * delta + np.einsum("bmj,sm->bsj", free, basis[:, 1:])
        return theta + arrays.start if order == 0 else theta

    weights = path.simpson_weights(problem.n_samples)
    distance = (np.sqrt(1.0 + angles(1) ** 2) * weights[:, None]).sum(axis=(1, 2))
    absolute = np.cumsum(angles(0), axis=-1)
    steps = np.stack([np.cos(absolute), np.sin(absolute)], -1) * arrays.lengths[:, None]
    ends = np.cumsum(steps, axis=-2)
    starts = np.concatenate([np.zeros_like(ends[..., :1, :]), ends[..., :-1, :]], axis=-2)
    world = arrays.world
    depth = np.zeros(len(x))
    for (cx, cy, radius), valid in zip(world.circles, world.circle_valid):
        if valid:
            d = ends - starts
            t = np.clip(((cx - starts[..., 0]) * d[..., 0] + (cy - starts[..., 1]) * d[..., 1])
                        / (d ** 2).sum(-1), 0, 1)
            gap = np.hypot(starts[..., 0] + t * d[..., 0] - cx,
                           starts[..., 1] + t * d[..., 1] - cy) - radius
            depth += np.maximum(-gap, 0).sum(axis=(1, 2))
    for p in np.nonzero(world.polygon_valid)[0]:
        normals = world.normals[p][world.edge_valid[p]]  # (E, 2)
        a, b = starts @ normals.T, ends @ normals.T  # (B, S, J, E)
        valid = world.edge_valid[p]
        low, high = world.extent_low[p][valid], world.extent_high[p][valid]
        gap = np.maximum(np.minimum(a, b) - high, low - np.maximum(a, b)).max(-1)
        d = ends - starts
        normal = np.stack([-d[..., 1], d[..., 0]], -1) / np.linalg.norm(d, axis=-1, keepdims=True)
        along = normal @ world.vertices[p].T  # (B, S, J, V)
        offset = (normal * starts).sum(-1)
        gap = np.maximum(gap, np.maximum(along.min(-1) - offset, offset - along.max(-1)))
        depth += np.maximum(-gap, 0).sum(axis=(1, 2))
    return np.where(depth > 0, 0.0, 1.0 / distance)


ARITHMETIC = {"add", "sub", "mul", "div", "max", "min", "neg", "abs", "sqrt", "rsqrt", "exp",
              "log", "pow", "integer_pow", "select_n", "lt", "gt", "le", "ge", "eq", "ne",
              "round", "floor", "sign", "and", "or", "not", "square", "sin", "cos"}


def count_flops(jaxpr) -> int:
    """Floating-point (and comparison/select) operations a jaxpr performs, loops unrolled.

    XLA's own cost analysis counts a loop body once, whatever its trip count; this walks the
    jaxpr instead, multiplying each ``scan`` body by its length.
    """
    total = 0
    for eqn in jaxpr.eqns:
        name = eqn.primitive.name
        if name == "scan":
            total += eqn.params["length"] * count_flops(eqn.params["jaxpr"].jaxpr)
        elif name in ARITHMETIC:
            total += int(np.prod(eqn.outvars[0].aval.shape))
        elif name.startswith("reduce_") and name != "reduce_precision":
            total += int(np.prod(eqn.invars[0].aval.shape))
        else:  # nested programs: pjit, custom_vmap, closed_call, ...
            for param in eqn.params.values():
                inner = getattr(param, "jaxpr", param)
                if hasattr(inner, "eqns"):
                    total += count_flops(inner)
    return total


def median_seconds(run, repeats: int) -> float:
    run()  # warm-up (and compilation)
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        run()
        times.append(time.perf_counter() - began)
    return float(np.median(times))


def interleaved_seconds(runs: dict, repeats: int) -> dict:
    """Median seconds of each run, timed in turns (a, b, a, b, ...) after a warm-up of each,
    so that a slow spell of the machine hits every run alike."""
    for run in runs.values():
        run()
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            began = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - began)
    return {name: float(np.median(t)) for name, t in times.items()}


def matmul_peak(repeats: int) -> float:
    """Measured float32 matmul GFLOP/s (4096 x 4096)."""
    a = jnp.ones((4096, 4096), jnp.float32)
    matmul = jax.jit(lambda a: a @ a)
    seconds = median_seconds(lambda: matmul(a).block_until_ready(), repeats)
    return 2 * 4096**3 / seconds / 1e9


def evaluate_section(repeats: int) -> None:
    """The ``--evaluate`` table (module docstring)."""
    certified = jaxarm.load_scenario("paper-case-1")
    x = jnp.asarray(np.random.default_rng(0).uniform(-100, 100, (20_000, 3)), jnp.float32)
    print(f"jax {jax.__version__} ({jax.default_backend()}), 20,000 paths of paper-case-1, "
          f"median of {repeats} calls in turns, warm\n")
    print("| check | called | fitness alone (s) | evaluate (s) | fitness + violation + "
          "travelling_distance (s) | evaluate / fitness |")
    print("|---|---|---|---|---|---|")
    for problem in (certified.replace(collision="sampled"), certified):
        three = (jaxarm.fitness, jaxarm.violation, jaxarm.travelling_distance)
        for called in ("from the host", "inside jax.jit"):
            wrap = jax.jit if called == "inside jax.jit" else (lambda f: f)
            fitness = wrap(lambda x, p=problem: jaxarm.fitness(p, x))
            evaluation = wrap(lambda x, p=problem: jaxarm.evaluate(p, x))
            separately = wrap(lambda x, p=problem: [f(p, x) for f in three])
            seconds = interleaved_seconds({
                "fitness": lambda: jax.block_until_ready(fitness(x)),
                "evaluate": lambda: jax.block_until_ready(evaluation(x)),
                "three": lambda: jax.block_until_ready(separately(x))}, repeats)
            print(f"| {problem.collision} | {called} | {seconds['fitness']:.4f} | "
                  f"{seconds['evaluate']:.4f} | {seconds['three']:.4f} | "
                  f"{seconds['evaluate'] / seconds['fitness']:.2f} |", flush=True)


def self_collision_section(repeats: int) -> None:
    """The ``--self-collision`` table (module docstring)."""
    print(f"jax {jax.__version__} ({jax.default_backend()}), jaxarm.fitness on 20,000 random "
          f"paths: the first call (compiling) once, then the median of {repeats} warm calls in "
          f"turns\n")
    jax.block_until_ready(jnp.zeros(1) + 1)  # the backend starts before the first timing
    print("| scene | check | first call without (s) | first call with (s) | without (s) "
          "| with self-collision (s) | with / without |")
    print("|---|---|---|---|---|---|---|")
    for name in ("paper-case-1", "five-link-detour", "kinematic-chain-10"):
        scene = jaxarm.load_scenario(name)
        x = jnp.asarray(np.random.default_rng(0).uniform(-100.0, 100.0, (20_000, scene.n_free)),
                        jnp.float32)
        scene = scene.replace(arm=jaxarm.Arm(scene.arm.lengths, self_collision=False))
        with_pairs = scene.replace(arm=jaxarm.Arm(scene.arm.lengths, self_collision=True))
        for check in ("sampled", "certified"):
            runs = {label: (lambda p=p.replace(collision=check):
                            jax.block_until_ready(jaxarm.fitness(p, x)))
                    for label, p in (("without", scene), ("with", with_pairs))}
            first = {}
            for label, run in runs.items():
                began = time.perf_counter()
                run()
                first[label] = time.perf_counter() - began
            seconds = interleaved_seconds(runs, repeats)
            n_pairs = len(jaxarm.model.self_collision.pairs(scene.n_joints))
            print(f"| {name} ({scene.n_joints} links, {n_pairs} pair{'s' * (n_pairs != 1)}) "
                  f"| {check} | {first['without']:.1f} | {first['with']:.1f} "
                  f"| {seconds['without']:.4f} | {seconds['with']:.4f} | "
                  f"{seconds['with'] / seconds['without']:.2f} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-batch", type=int, default=1_000_000)
    parser.add_argument("--numpy-max-batch", type=int, default=100_000)
    parser.add_argument("--certified-max-batch", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--evaluate", action="store_true")
    parser.add_argument("--self-collision", action="store_true")
    args = parser.parse_args()
    if args.self_collision:
        self_collision_section(args.repeats)
        return
    if args.evaluate:
        evaluate_section(args.repeats)
        return

    certified = jaxarm.load_scenario("paper-case-1")  # certified: the default
    problem = certified.replace(collision="sampled")
    rng = np.random.default_rng(0)
    kernel = jax.jit(evaluate, static_argnums=0)

    check = rng.uniform(-300, 300, (20_000, 3))
    ours = np.asarray(jaxarm.fitness(problem, check.astype(np.float32)))
    reference = numpy_fitness(problem, check)
    agree = np.mean((ours > 0) == (reference > 0))
    both = (ours > 0) & (reference > 0)
    relative = np.max(np.abs(ours[both] - reference[both]) / reference[both]) if both.any() else 0
    print(f"jax {jax.__version__} ({jax.default_backend()}, {len(jax.devices())} device(s)), "
          f"numpy {np.__version__}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores")
    print(f"NumPy reference agrees on feasibility for {agree:.4%} of 20,000 random paths "
          f"({both.sum()} feasible); max relative fitness difference {relative:.1e}")

    x_one = jnp.zeros((1, 3), jnp.float32)
    flops = {mode: count_flops(jax.make_jaxpr(lambda x, p=p: evaluate(p.spec, p.arrays, x))(
        x_one).jaxpr) for mode, p in (("sampled", problem), ("certified", certified))}
    peak = matmul_peak(args.repeats)

    print("\n| batch | jaxarm sampled (paths/s) | jaxarm certified (paths/s) "
          "| certified / sampled "
          "| NumPy (paths/s) | jaxarm / NumPy |")
    print("|---|---|---|---|---|---|")
    batch = 1_000
    best_sampled = 0.0
    while batch <= args.max_batch:
        x = jnp.asarray(rng.uniform(-100, 100, (batch, 3)), jnp.float32)
        modes = {"sampled": problem}
        if batch <= args.certified_max_batch:
            modes["certified"] = certified
        seconds = interleaved_seconds(
            {mode: (lambda p=p: kernel(p.spec, p.arrays, x).fitness.block_until_ready())
             for mode, p in modes.items()}, args.repeats)
        rate = {mode: batch / s for mode, s in seconds.items()}
        best_sampled = max(best_sampled, rate["sampled"])
        certified_cells = (f"{rate['certified']:,.0f} | {rate['certified'] / rate['sampled']:.0%}"
                           if "certified" in rate else "– | –")
        if batch <= args.numpy_max_batch:
            x64 = np.asarray(x, np.float64)
            numpy_rate = batch / median_seconds(lambda: numpy_fitness(problem, x64),
                                                max(1, args.repeats // 2))
            numpy_cells = f"{numpy_rate:,.0f} | {rate['sampled'] / numpy_rate:.1f}x"
        else:
            numpy_cells = "– | –"
        print(f"| {batch:,} | {rate['sampled']:,.0f} | {certified_cells} | {numpy_cells} |")
        batch *= 10
    print(f"\nWork per path (operations in the jaxpr, loops unrolled): sampled "
          f"{flops['sampled']:,.0f} flop, certified "
          f"{flops['certified']:,.0f} flop. Measured float32 matmul peak: {peak:,.1f} GFLOP/s; "
          f"the best sampled rate is {best_sampled * flops['sampled'] / 1e9:,.2f} GFLOP/s, "
          f"{best_sampled * flops['sampled'] / 1e9 / peak:.1%} of it.")


if __name__ == "__main__":
    main()
