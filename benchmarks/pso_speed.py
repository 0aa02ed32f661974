"""The PSO's speed before and after a change, for the paper's presets.

Each of A, B and C (death penalty, the paper's sampled check, paper-case-1) runs a 1000-seed x
20-particle x 100-iteration ``solve``, in this checkout and in a git worktree of ``--baseline``,
in fresh processes taken in turns (baseline, current, baseline, current, ...). Each process
compiles first, then times ``--repeats`` calls with new seeds; the table gives the median
seconds per tree and their ratio.

    .venv/bin/python benchmarks/pso_speed.py --baseline becbde2 [--rounds 2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

TIMING = """
import json, sys, time
sys.path.insert(0, {root!r})
import jaxarm
assert jaxarm.__file__.startswith({root!r}), jaxarm.__file__
problem = jaxarm.load_scenario("paper-case-1").replace(collision="sampled")
times = {{}}
for method in ("A", "B", "C"):
    jaxarm.solve(problem, method, n_restarts=1000, seed=0)  # compile
    times[method] = []
    for seed in range(1, {repeats} + 1):
        began = time.perf_counter()
        jaxarm.solve(problem, method, n_restarts=1000, seed=seed)
        times[method].append(time.perf_counter() - began)
print(json.dumps(times))
"""


def time_tree(root: pathlib.Path, repeats: int) -> dict:
    done = subprocess.run([sys.executable, "-c", TIMING.format(root=str(root), repeats=repeats)],
                          capture_output=True, text=True, check=True, cwd=root)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", required=True, help="a git commit to compare with")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    current = pathlib.Path(__file__).resolve().parents[1]
    commit = subprocess.run(["git", "rev-parse", "--short", args.baseline], cwd=current,
                            capture_output=True, text=True, check=True).stdout.strip()
    with tempfile.TemporaryDirectory() as scratch:
        baseline = pathlib.Path(scratch) / "baseline"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(baseline), commit],
                       cwd=current, check=True)
        try:
            times = {"baseline": {}, "current": {}}
            for _ in range(args.rounds):
                for name, root in (("baseline", baseline), ("current", current)):
                    for method, seconds in time_tree(root, args.repeats).items():
                        times[name].setdefault(method, []).extend(seconds)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(baseline)], cwd=current,
                           check=True)
    print(f"paper-case-1, sampled check, death penalty, 1000 seeds x 20 particles x 100 "
          f"iterations; {args.rounds} rounds x {args.repeats} calls per tree, medians\n")
    print(f"| preset | baseline {commit} (s) | current (s) | current / baseline |")
    print("|---|---|---|---|")
    for method in ("A", "B", "C"):
        before, after = (float(np.median(times[name][method])) for name in times)
        print(f"| {method} | {before:.3f} | {after:.3f} | {after / before:.2f} |")


if __name__ == "__main__":
    main()
