"""How high a path degree jaxarm computes well: the measurement behind ``MAX_DEGREE``.

For each degree, paths of paper-case-2 (3 links, 101 samples) are evaluated in float32, as
the search does, and in float64 (``jax.enable_x64``), and compared:

- ``angle err``: max |theta_32 - theta_64| over the samples and joints (rad), and
  ``rel``: that error over max |theta_64| (the path's own scale);
- ``speed rel``: the same for d theta / dr, relative to max |d theta / dr|;
- ``dist rel``: max relative error of the travelling distance (eq. 5, Simpson) and so of the
  fitness 1 / distance;
- ``simpson rel``: max relative error of the float64 Simpson distance at the 101 samples
  against one at 100,001 samples (the quadrature's own error, not float32's).

Two families of paths: ``init`` draws every free coefficient from the default initial range
[-100, 100] (the first swarm); ``small`` scales those coefficients so that the path strays at
most 1 rad from the quintic between start and goal (the paths a search ends with).

Up to ``--certified-up-to``, a fresh process per degree (its own empty compilation cache) also
runs the certified check, the default, and reports:

- ``certified``: whether its float32 verdicts on the ``small`` paths are finite and agree with
  float64's (share of the paths);
- ``search s``: wall time of ``jaxarm solve paper-case-2 --degree D --method A --particles 2
  --iters 1``'s search (``jaxarm.solve``), nearly all of it compilation, and ``peak GB``: the
  process's peak memory; a process still running after ``--timeout`` seconds is stopped.

    .venv/bin/python benchmarks/degree_limit.py [--degrees 6,8,...] [--paths 64]
        [--certified-up-to 32] [--timeout 600]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

import jax
import numpy as np

import jaxarm
from jaxarm.model import path

DEGREES = "6,8,12,16,20,24,28,32,48,64,96,128,170,200"
path.MAX_DEGREE = 1000  # lifted, to measure past the limit


def _paths(problem, rng, n_paths: int, family: str) -> np.ndarray:
    x = rng.uniform(-100.0, 100.0, (n_paths, problem.n_free))
    if family == "small":  # scale each path so the free part strays at most 1 rad
        r = np.linspace(0.0, 1.0, 1001)
        basis = path.basis_values(problem.degree, r)[:, 1:]  # the g_p, shape (n_r, d - 5)
        free = path.free_by_joint(x, problem.n_joints)  # (n_paths, d - 5, n_joints)
        stray = np.abs(np.einsum("rp,bpj->brj", basis, free)).max(axis=(1, 2))
        x = x / stray[:, None]
    return x


def _errors(problem, x: np.ndarray) -> dict:
    r = np.linspace(0.0, 1.0, problem.n_samples)
    single = {order: np.asarray(jaxarm.joint_path(problem, x.astype(np.float32), r, order))
              for order in (0, 1)}
    distance = np.asarray(jaxarm.travelling_distance(problem, x.astype(np.float32)))
    with jax.enable_x64(True):
        double = {order: np.asarray(jaxarm.joint_path(problem, x, r, order)) for order in (0, 1)}
        exact = np.asarray(jaxarm.travelling_distance(problem, x))
        dense = np.asarray(jaxarm.travelling_distance(problem.replace(n_samples=100_001), x))
    angle = np.abs(single[0] - double[0]).max()
    speed = np.abs(single[1] - double[1]).max()
    return {"angle": angle, "angle_rel": angle / np.abs(double[0]).max(),
            "speed_rel": speed / np.abs(double[1]).max(),
            "dist_rel": float(np.max(np.abs(distance - exact) / exact)),
            "simpson_rel": float(np.max(np.abs(exact - dense) / dense))}


def _certified_child(degree: int, n_paths: int) -> None:
    """In a fresh process: the search's time, then float32 against float64 verdicts."""
    problem = jaxarm.load_scenario("paper-case-2", degree=degree)
    began = time.perf_counter()
    jaxarm.solve(problem, "A", n_particles=2, n_iters=1, n_restarts=1)
    seconds = time.perf_counter() - began
    x = _paths(problem, np.random.default_rng(degree), n_paths, "small")
    single = jaxarm.certify(problem, x.astype(np.float32))
    with jax.enable_x64(True):
        double = jaxarm.certify(problem, x)
    finite = bool(np.all(np.isfinite(np.asarray(single.clearance))))
    agree = float(np.mean((np.asarray(single.free) == np.asarray(double.free))
                          & (np.asarray(single.colliding) == np.asarray(double.colliding))))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6  # kB on Linux
    print(json.dumps({"seconds": seconds, "finite": finite, "agree": agree, "peak": peak}))


def _certified(degree: int, n_paths: int, timeout: float) -> tuple[str, str, str]:
    with tempfile.TemporaryDirectory() as cache:
        command = [sys.executable, __file__, "--child", str(degree), "--paths", str(n_paths)]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout,
                                  env=os.environ | {"JAXARM_CACHE_DIR": cache})
        except subprocess.TimeoutExpired:
            return "-", f"> {timeout:.0f} (stopped)", "-"
    if done.returncode != 0:
        return f"fails: {done.stderr.strip().splitlines()[-1][:60]}", "-", "-"
    out = json.loads(done.stdout.strip().splitlines()[-1])
    verdict = f"agree {out['agree']:.3f}" if out["finite"] else "non-finite"
    return verdict, f"{out['seconds']:.1f}", f"{out['peak']:.1f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--degrees", default=DEGREES)
    parser.add_argument("--paths", type=int, default=64)
    parser.add_argument("--certified-up-to", type=int, default=32)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        return _certified_child(args.child, args.paths)
    print(f"jax {jax.__version__} ({jax.default_backend()}), "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"{args.paths} paths per family\n")
    print("| degree | family | angle err (rad) | rel | speed rel | dist rel | simpson rel | "
          "certified | search s | peak GB |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    base = jaxarm.load_scenario("paper-case-2", collision="sampled")
    for degree in (int(d) for d in args.degrees.split(",")):
        problem = base.replace(degree=degree)
        for family in ("init", "small"):
            x = _paths(problem, np.random.default_rng(degree), args.paths, family)
            e = _errors(problem, x)
            cells = (_certified(degree, args.paths, args.timeout)
                     if family == "small" and degree <= args.certified_up_to else ("",) * 3)
            print(f"| {degree} | {family} | {e['angle']:.2e} | {e['angle_rel']:.1e} | "
                  f"{e['speed_rel']:.1e} | {e['dist_rel']:.1e} | {e['simpson_rel']:.1e} | "
                  + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
