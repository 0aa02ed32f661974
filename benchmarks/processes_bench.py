"""One process against two: a 10,000-seed escape study through the CLI, wall time per run.

Each run is a fresh ``jaxarm study paper-case-1 --collision sampled --methods A`` (import,
compilation and the study); two processes join over gloo on 127.0.0.1 and split the restarts.
Runs alternate one / two processes; the table gives medians. Both write the same CSV
(checked).

    .venv/bin/python benchmarks/processes_bench.py [--seeds 10000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def run(n_processes: int, n_restarts: int, csv: str) -> float:
    command = [sys.executable, "-m", "jaxarm"]
    study = ["study", "paper-case-1", "--collision", "sampled", "--methods", "A",
             "--restarts", str(n_restarts), "--csv", csv]
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    began = time.perf_counter()
    if n_processes == 1:
        subprocess.run(command + study, env=env, check=True, capture_output=True)
    else:
        port = free_port()
        processes = [subprocess.Popen(
            command + ["--coordinator", f"127.0.0.1:{port}", "--num-processes",
                       str(n_processes), "--process-id", str(i)] + study,
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for i in range(n_processes)]
        if any(p.wait() for p in processes):
            raise SystemExit("a process failed")
    return time.perf_counter() - began


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restarts", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    times = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as scratch:
        outputs = {n: os.path.join(scratch, f"{n}.csv") for n in times}
        for _ in range(args.repeats):
            for n in times:
                times[n].append(run(n, args.restarts, outputs[n]))
        same = open(outputs[1]).read() == open(outputs[2]).read()
    print(f"{os.cpu_count()} CPU cores, {args.restarts} seeds, {args.repeats} runs each; "
          f"same CSV from 1 and 2 processes: {same}")
    print("| processes | wall time per run, median (s) | runs (s) |")
    print("|---|---|---|")
    for n, values in times.items():
        print(f"| {n} | {np.median(values):.1f} | {', '.join(f'{v:.1f}' for v in values)} |")
    print(f"two / one: {np.median(times[2]) / np.median(times[1]):.2f}")


if __name__ == "__main__":
    main()
