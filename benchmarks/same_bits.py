"""Fingerprints of jaxarm's answers, to show that a change which should keep every bit does.

Run it before a change (``--save before.npz``) and after (``--save after.npz --compare
before.npz``): it computes fitness, violation, certify, solve (both checks, the death penalty
and feasibility rules, the default search), an escape study under several constraint rules,
and trajectories on seven shipped scenes, and compares every array bit for bit. The arrays are
machine-specific (XLA's CPU code differs between processors), so the two runs belong on one
machine; the result of the last comparison lives in ``benchmarks/RESULTS.md``, *Same bits*.

    python benchmarks/same_bits.py --save /tmp/before.npz
    python benchmarks/same_bits.py --save /tmp/after.npz --compare /tmp/before.npz
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import jaxarm

SCENES = ("paper-case-1", "paper-case-2", "paper-case-3", "death-trap", "polygon-field",
          "narrow-gap", "five-link-detour")
N_PATHS = 48
N_RESTARTS = 8
N_PARTICLES = 10
N_ITERS = 20


def fingerprints(scenes=SCENES) -> dict[str, np.ndarray]:
    """Every answer as an array, keyed ``scene/what``."""
    out = {}
    for name in scenes:
        for collision in ("certified", "sampled"):
            problem = jaxarm.load_scenario(name).replace(collision=collision)
            rng = np.random.default_rng(0)
            low, high = problem.bounds()
            x = rng.uniform(low, high, (N_PATHS, problem.n_free)).astype(np.float32)
            key = f"{name}/{collision}"
            out[f"{key}/fitness"] = np.asarray(jaxarm.fitness(problem, x))
            out[f"{key}/violation"] = np.asarray(jaxarm.violation(problem, x))
            out[f"{key}/distance"] = np.asarray(jaxarm.travelling_distance(problem, x))
            if collision == "certified":
                certificate = jaxarm.certify(problem, x)
                for field, value in certificate._asdict().items():
                    out[f"{key}/certify/{field}"] = np.asarray(value)
            for method in ("A", "A:feasibility", "B:epsilon"):
                result = jaxarm.solve(problem, method, n_restarts=N_RESTARTS,
                                      n_particles=N_PARTICLES, n_iters=N_ITERS, seed=3)
                for field, value in result.restarts._asdict().items():
                    out[f"{key}/solve/{method}/{field}"] = np.asarray(value)
                out[f"{key}/solve/{method}/certified"] = np.asarray(result.certified)
        problem = jaxarm.load_scenario(name)
        result = jaxarm.solve(problem, seed=1)  # the default search
        for field, value in result.restarts._asdict().items():
            out[f"{name}/default/{field}"] = np.asarray(value)
        out[f"{name}/default/certified"] = np.asarray(result.certified)
        study = jaxarm.escape_study(problem, ["A", "A:feasibility", "C:penalty"],
                                    n_restarts=N_RESTARTS, n_particles=N_PARTICLES,
                                    n_iters=N_ITERS, seed=5, progress=False)
        for label in ("A", "A:feasibility", "C:penalty"):
            for field, value in study.method(label).outcome._asdict().items():
                out[f"{name}/study/{label}/{field}"] = np.asarray(value)
        if result.certified:
            trajectory = jaxarm.Trajectory(problem, result.best_x, duration=2.0)
            t = np.linspace(0.0, 2.0, 41)
            for field, value in trajectory.at(t)._asdict().items():
                out[f"{name}/trajectory/{field}"] = np.asarray(value)
            if problem.arm.masses is not None:
                out[f"{name}/trajectory/torques"] = np.asarray(trajectory.torques(t))
            out[f"{name}/min_duration"] = np.asarray(jaxarm.min_duration(
                problem, result.best_x, max_velocity=1.0, max_acceleration=2.0))
        print(f"{name}: {len(out)} arrays so far", file=sys.stderr, flush=True)
    return out


def compare(now: dict, before: dict) -> list[str]:
    """The keys whose arrays differ in any bit (or exist in one run only)."""
    differ = []
    for key in sorted(set(now) | set(before)):
        if key not in now or key not in before:
            differ.append(f"{key}: only {'before' if key in before else 'now'}")
            continue
        a, b = np.asarray(now[key]), np.asarray(before[key])
        if a.shape != b.shape or a.dtype != b.dtype or a.tobytes() != b.tobytes():
            differ.append(f"{key}: differs")
    return differ


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", required=True, help="write the fingerprints to this .npz")
    parser.add_argument("--compare", help="a .npz from an earlier run to compare with")
    parser.add_argument("--scenes", default=",".join(SCENES))
    args = parser.parse_args()
    now = fingerprints(args.scenes.split(","))
    np.savez(args.save, **now)
    print(f"{len(now)} arrays written to {args.save}")
    if args.compare:
        before = dict(np.load(args.compare))
        differ = compare(now, before)
        for line in differ:
            print(line)
        print(f"{len(now)} arrays now, {len(before)} before: {len(differ)} differ")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
