"""The ``jaxarm`` command: scenarios, solve, study, reproduce-paper.

Errors (unknown or misspelt flags, missing file, malformed TOML, bad values, unreachable pose,
colliding start, an output that cannot be written) print one line to stderr and exit with
status 2, before any search where the input decides them; ``--debug`` shows the traceback
instead. Ctrl-C prints one line and exits with 130; output files are written whole or not at
all.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import json
import logging
import os
import pathlib
import re
import sys
import tempfile

from jaxarm.choices import (
    CLUTTER_KINDS,
    COLLISION_MODES,
    CONSTRAINTS,
    DEFAULT_CONSTRAINT,
    DEFAULT_METHODS,
    DEFAULT_RESTARTS,
    DEFAULT_TIME_LIMIT,
    LIMIT_UNITS,
    MAX_DEGREE,
    MIN_DEGREE,
    PSO_METHODS,
    split_methods,
)

EXIT_ERROR = 2
EXPORT_RATE = 100.0  # Hz, --export's samples per second unless --rate says otherwise
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


class _Parser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose errors are one line (``--help`` shows the usage), and
    which reads ``-1e4``, ``-.5`` and ``-inf`` as numbers rather than as unknown flags."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)(e[-+]?\d+)?$|^-inf$",
                                                   re.IGNORECASE)

    def error(self, message: str):
        self.exit(EXIT_ERROR, f"{self.prog}: error: {message}\n")


def _version() -> str:
    from jaxarm import __version__

    return __version__


def _at_least(minimum: int):
    def parse(text: str) -> int:
        value = int(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        return value

    parse.__name__ = "integer"  # argparse names the type in its messages
    return parse


_positive = _at_least(1)


def _seed(text: str) -> int:
    from jaxarm._validate import check_seed

    try:
        return check_seed(int(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, 2**31), got {text}")


_seed.__name__ = "seed"


def _positive_seconds(text: str) -> float:
    value = float(text)
    if not value > 0:  # NaN too
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


_positive_seconds.__name__ = "seconds"


def _degrees(text: str) -> tuple[int, ...]:
    try:
        degrees = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be comma-separated integers, got {text!r}")
    if min(degrees) < MIN_DEGREE:
        raise argparse.ArgumentTypeError(f"degrees must be >= {MIN_DEGREE}, got {text!r}")
    if max(degrees) > MAX_DEGREE:
        raise argparse.ArgumentTypeError(f"degrees must be <= {MAX_DEGREE}, got {text!r}")
    if len(set(degrees)) < len(degrees):
        raise argparse.ArgumentTypeError(f"degrees must not repeat a degree, got {text!r}")
    return degrees


def _limit_values(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number or comma-separated numbers (one per "
                                         f"joint), got {text!r}")
    return values


def _add_common_options(parser: argparse.ArgumentParser) -> None:
    # SUPPRESS: given after the subcommand it sets the flag, absent it keeps the main parser's
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                        help="no notices on stderr while programs compile")


def _add_search_options(parser: argparse.ArgumentParser) -> None:
    _add_common_options(parser)
    parser.add_argument("scenario", help="a shipped scenario name or a path to a .toml file")
    parser.add_argument("--constraint", choices=CONSTRAINTS,
                        help="constraint handling (default: the rule a method names, as in "
                             "A:feasibility, else death, the paper's)")
    parser.add_argument("--particles", type=_at_least(2), default=20,
                        help="swarm size, >= 2 (20)")
    parser.add_argument("--iters", type=_positive, default=100, help="PSO iterations (100)")
    parser.add_argument("--seed", type=_seed, default=0, help="base seed (0)")
    parser.add_argument("--collision", choices=COLLISION_MODES,
                        help="collision check (default: the scenario's, else certified; "
                             "sampled is the paper's check at the samples only)")
    parser.add_argument("--margin", type=float,
                        help="clearance in cm every link keeps from obstacles (default: the "
                             "scenario's, else 0)")
    parser.add_argument("--degree", type=int,
                        help=f"polynomial degree, {MIN_DEGREE} to {MAX_DEGREE} (default: the "
                             "scenario's)")
    parser.add_argument("--samples", type=int,
                        help="odd number of points of r (default: the scenario's, else 101)")
    parser.add_argument("--init-low", type=float, metavar="LOW",
                        help="low end of the initial swarm's range, every coefficient "
                             "(default: the scenario's)")
    parser.add_argument("--init-high", type=float, metavar="HIGH",
                        help="high end of the initial swarm's range (default: the scenario's)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="jaxarm",
        description="Smooth collision-free joint paths for planar arms by batched PSO (JAX).",
    )
    parser.add_argument("--version", action="version", version=f"jaxarm {_version()}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true",
                        help="no notices on stderr while programs compile")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not keep compiled and traced programs on disk (default: keep "
                             "them in $JAXARM_CACHE_DIR, else ~/.cache/jaxarm/xla)")
    _add_process_options(parser)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_common_options(commands.add_parser(
        "scenarios", help="list the shipped scenarios",
        description="List the shipped scenarios with one-line descriptions."))
    _add_solve_command(commands)
    _add_study_command(commands)
    _add_clutter_command(commands)
    _add_reproduce_command(commands)
    return parser


def _add_process_options(parser: argparse.ArgumentParser) -> None:
    """The flags that run one command over several processes or machines."""
    processes = parser.add_argument_group(
        "several processes or machines",
        "Run the same command in every process; restarts are split over all of them, every "
        "process computes the same result, process 0 prints and writes files. "
        "JAXARM_DISTRIBUTED=1 without these flags uses jax.distributed's own detection "
        "(SLURM, ...).")
    processes.add_argument("--coordinator", metavar="HOST:PORT",
                           help="address of process 0's coordination service")
    processes.add_argument("--num-processes", type=_positive, metavar="N",
                           help="how many processes take part")
    processes.add_argument("--process-id", type=int, metavar="I",
                           help="this process's number, 0 .. N-1")


def _add_solve_command(commands) -> None:
    """``jaxarm solve``: the search, its outputs and the best path's timing."""
    solve = commands.add_parser("solve", help="search one scenario and print the best path",
                                description="Run PSO restarts on a scenario; print a summary.")
    _add_search_options(solve)
    solve.add_argument("--method", metavar="METHOD",
                       help=f"the paper's preset, or one with the ring (A-ring) or "
                            f"global-then-ring (A-global-ring) topology: one of "
                            f"{', '.join(PSO_METHODS)}, optionally with PSOConfig fields "
                            f"changed in brackets, such as 'A-ring[inertia_end=0.4]', and a "
                            f"constraint rule after a colon ('A:feasibility'); or "
                            f"evosax:<Strategy>. Default: {DEFAULT_RESTARTS} restarts each of "
                            f"{' and '.join(DEFAULT_METHODS)} with {DEFAULT_CONSTRAINT} rules, "
                            f"the search meant to find a collision-free path; 'A' is the "
                            f"paper's preset with its death penalty, one swarm")
    solve.add_argument("--restarts", type=_positive,
                       help=f"independent swarms ({DEFAULT_RESTARTS} per default method, "
                            f"1 with a named one)")
    solve.add_argument("--time-limit", type=_positive_seconds, metavar="S",
                       help=f"seconds the search may go on while no path is certified free: "
                            f"more restarts, then higher degrees seeded with the best paths so "
                            f"far, one line per stage on stderr (default: "
                            f"{DEFAULT_TIME_LIMIT:g} with the default method; a named method "
                            f"runs once unless given one)")
    solve.add_argument("--improve", action="store_true",
                       help="go on after a certified path is found, until the time limit, "
                            "keeping the fittest (default: stop at the first stage that "
                            "certifies one)")
    solve.add_argument("--refine", choices=("best", "all"),
                       help="polish with gradient steps after PSO: the best restart, or every "
                            "feasible one (default: no refinement)")
    solve.add_argument("--json", type=pathlib.Path,
                       help="write the result, the problem and the settings as JSON")
    solve.add_argument("--plot", type=pathlib.Path,
                       help="write the motion as a figure (.png, .pdf or .svg)")
    solve.add_argument("--gif", type=pathlib.Path, help="write an animation of the motion (.gif)")
    _add_timing_options(solve)


def _add_timing_options(solve: argparse.ArgumentParser) -> None:
    """``solve``'s flags that time the best path and export the trajectory."""
    timing = solve.add_argument_group(
        "trajectory in seconds",
        "Time the best path: a given --duration, or the shortest one that meets the --max-* "
        "limits (each a number for every joint, or one per joint, comma-separated).")
    timing.add_argument("--duration", type=float, metavar="SECONDS",
                        help="transfer time T of the best path")
    for name, unit in LIMIT_UNITS.items():
        timing.add_argument(f"--max-{name}", type=_limit_values, metavar="LIMIT",
                            help=f"{name} limit ({unit}); the duration becomes the shortest "
                                 "that meets every limit given")
    timing.add_argument("--export", type=pathlib.Path, metavar="FILE",
                        help="write the trajectory at --rate Hz (.csv, or .csv.gz compressed: "
                             "t, q, dq, ddq and tau columns when the arm's masses are known; "
                             ".json)")
    timing.add_argument("--rate", type=float,
                        help=f"samples per second of --export ({EXPORT_RATE:g})")


def _add_clutter_command(commands) -> None:
    """``jaxarm clutter``: a scenario with random obstacles added, written as a file."""
    clutter = commands.add_parser(
        "clutter", help="add random obstacles to a scenario and write it as a new file",
        description="Add COUNT random obstacles within the arm's reach, the start and goal "
                    "kept clear, and write the scenario to --output.")
    _add_common_options(clutter)
    clutter.add_argument("scenario", help="a shipped scenario name or a path to a .toml file")
    clutter.add_argument("--count", type=_positive, required=True, help="obstacles to add")
    clutter.add_argument("--kind", choices=CLUTTER_KINDS, default="circles",
                         help="their shape (circles)")
    clutter.add_argument("--size", type=float, nargs=2, default=(1.0, 3.0),
                         metavar=("MIN", "MAX"), help="circumradius range in cm (1 3)")
    clutter.add_argument("--seed", type=_seed, default=0, help="the random stream (0)")
    clutter.add_argument("--clear-path", action="store_true",
                         help="keep the path with no free coefficients clear too, so that the "
                              "scene has a collision-free motion")
    clutter.add_argument("--output", "-o", type=pathlib.Path, required=True,
                         help="the scenario file to write (.toml)")


def _clutter(args) -> None:
    from jaxarm.io.scenario_files import load_scenario, save_scenario
    from jaxarm.model.clutter import clutter

    if args.output.suffix != ".toml":  # exactly: as save_scenario and load_scenario read it
        raise ValueError(f"--output must end in .toml, got {str(args.output)!r}")
    _check_outputs(args)
    try:
        problem = clutter(load_scenario(args.scenario), args.count, args.kind, args.size,
                          args.seed, clear_path=0 if args.clear_path else None)
    except ValueError as error:
        raise ValueError(_flag_names(str(error))) from None
    _write(args.output, lambda path: save_scenario(problem, path))
    print(problem.summary())


def _as_flag(flag: str, check, *args):
    """``check(*args)``, its ValueError about ``method`` naming ``flag`` instead."""
    try:
        return check(*args)
    except ValueError as error:
        raise ValueError(re.sub(r"^method\b", flag, str(error))) from None


def _flag_names(message: str) -> str:
    """An error of ``jaxarm.clutter`` with its arguments named as the flags."""
    return re.sub(r"^(count|size|seed)\b", lambda m: f"--{m.group()}", message)


def _add_study_command(commands) -> None:
    """``jaxarm study``: the escape study and its outputs."""
    study = commands.add_parser("study", help="escape probability over many seeds",
                                description="Escape-probability study: every method over the "
                                            "same seeds, with 95 % Wilson intervals.")
    _add_search_options(study)
    study.add_argument("--restarts", type=_positive, default=500,
                       help="restarts per method (500); restart i is seeded by (--seed, i)")
    study.add_argument("--methods", default="A,B,C",
                       help="comma-separated: A, B, C, A-ring (preset A, ring topology), "
                            "A-global-ring (the global best for 5 %% of the iterations, then the "
                            "ring), any of them with PSOConfig fields changed in brackets "
                            "('A-ring[inertia_end=0.4]'), METHOD:CONSTRAINT, or an evosax "
                            "strategy such as evosax:CMA_ES or evosax:DE:feasibility (needs "
                            "evosax) (A,B,C)")
    study.add_argument("--chunk-size", type=_positive, default=500,
                       help="at most this many restarts per compiled call; bounds memory and "
                            "sets how often the progress bar moves, results do not depend on "
                            "it (500)")
    study.add_argument("--checkpoint", type=pathlib.Path, metavar="DIR",
                       help="save each finished chunk in DIR (created if need be); the same "
                            "command again resumes from it, to the same results")
    study.add_argument("--pairwise", action="store_true",
                       help="also print every pair's difference in escape rate (95 %% Newcombe "
                            "interval, Fisher exact p) and McNemar's exact p on the paired seeds")
    study.add_argument("--json", type=pathlib.Path, help="write summaries as JSON")
    study.add_argument("--csv", type=pathlib.Path, help="write per-seed records as CSV")
    study.add_argument("--plot", type=pathlib.Path,
                       help="write escape rates as a figure (.png, .pdf or .svg)")


def _add_reproduce_command(commands) -> None:
    """``jaxarm reproduce-paper``: the report's sizes and where it goes."""
    reproduce = commands.add_parser(
        "reproduce-paper", help="run the paper's experiments and write a report",
        description="Tables 2-6 of the paper, a large escape study, the constraint rules, "
                    "the path degrees and the shipped suite (--quick: the paper's tables and "
                    "the rules at demo sizes); writes OUT/report.md with tables and figures.")
    _add_common_options(reproduce)
    reproduce.add_argument("--out", type=pathlib.Path, default=pathlib.Path("results"),
                           help="output folder (results)")
    reproduce.add_argument("--quick", action="store_true",
                           help="the demo: the paper's tables and the constraint rules at 100 "
                                "seeds; the suite and the degrees only when named")
    reproduce.add_argument("--restarts", type=_positive,
                           help="restarts of the case-1 study and the rules section (500; 100 "
                                "with --quick)")
    reproduce.add_argument("--suite", help="comma-separated scenarios for the suite study "
                                           "(default: all shipped but clutter-100, "
                                           "clutter-500 and workcell-map; none with --quick)")
    reproduce.add_argument("--suite-restarts", type=_positive,
                           help="restarts per suite scenario (200; 50 with --quick)")
    reproduce.add_argument("--degrees", type=_degrees,
                           help="path degrees compared beyond the paper (6,7,8; none with "
                                "--quick)")
    reproduce.add_argument("--workers", type=_positive,
                           help="threads running the report's sections side by side (default: "
                                "the cores available, at most 5; 1 under jax.distributed); "
                                "results do not depend on it")


def _check_outputs(args) -> None:
    """Every output file can be written and every figure's suffix is known, before any work."""
    from jaxarm.io.files import output_file

    suffixes = {"plot": FIGURE_SUFFIXES, "gif": (".gif",),
                "export": (".csv", ".csv.gz", ".json")}
    for name in ("json", "csv", "plot", "gif", "export", "output"):
        path = getattr(args, name, None)
        if path is None:
            continue
        flag = f"--{name}"
        suffix = "".join(path.suffixes[-2:] if path.suffix == ".gz" else path.suffixes[-1:])
        if name in suffixes and suffix.lower() not in suffixes[name]:
            raise ValueError(f"{flag} must end in {', '.join(suffixes[name])}, got {str(path)!r}")
        output_file(flag, path)


def _write(path: pathlib.Path, write) -> None:
    """``write(temporary_path)``, then the file at ``path``, whole (``io.files.written``)."""
    from jaxarm.io.files import written

    with written(path) as temporary:
        write(temporary)
    print(f"wrote {path}")


# Command-line flags that override a scenario's Problem fields; the error names the flag.
_OVERRIDES = {"collision": "collision", "degree": "degree", "samples": "n_samples",
              "margin": "margin", "init_low": "init_low", "init_high": "init_high"}


def _load(args):
    from jaxarm.io.scenario_files import load_scenario, obstacle_names, with_file_names

    problem = load_scenario(args.scenario)
    overrides = {field: getattr(args, flag) for flag, field in _OVERRIDES.items()
                 if getattr(args, flag) is not None}
    if "degree" in overrides:
        kept = [field for field in ("init_low", "init_high")
                if field not in overrides and isinstance(getattr(problem, field), tuple)]
        if kept:
            raise ValueError(f"--degree {args.degree}: {problem.name}'s {kept[0]} has one value "
                             f"per coefficient of degree {problem.degree}; give --init-low "
                             "and --init-high too")
    try:
        return problem.replace(**overrides) if overrides else problem
    except ValueError as combined:  # obstacles named as the scenario file names them
        named = functools.partial(with_file_names, names=obstacle_names(args.scenario))
        flags = {field: f"--{flag.replace('_', '-')}" for flag, field in _OVERRIDES.items()
                 if field in overrides}
        for field, flag in flags.items():  # the flag that fails alone is the one to name
            try:
                problem.replace(**{field: overrides[field]})
            except ValueError as error:
                raise ValueError(f"{flag}: {named(str(error))}") from None
        raise ValueError(f"{', '.join(flags.values())}: {named(str(combined))}") from None


def _scenarios(args) -> None:
    from jaxarm.io.scenario_files import available

    names = available()
    width = max(map(len, names))
    for name, description in names.items():
        print(f"{name:<{width}}  {description}")


def _check_settings(args) -> None:
    from jaxarm._validate import check_search

    if args.command == "study":
        at_once = min(args.chunk_size, args.restarts)
    else:  # solve: every restart of a method at once
        at_once = args.restarts or (1 if args.method else DEFAULT_RESTARTS)
    check_search(n_particles=args.particles, n_iters=args.iters, seed=args.seed,
                 constraint=args.constraint or "death", restarts_at_once=at_once)


def _timing_limits(args, problem) -> dict:
    """The --max-* limits as ``min_duration`` keywords, checked against the problem."""
    from jaxarm._validate import positive_scalar
    from jaxarm.trajectory import MIN_DURATION, per_joint_limit

    limits = {}
    for name in LIMIT_UNITS:
        values = getattr(args, f"max_{name}")
        if values is None:
            continue
        try:
            limits[f"max_{name}"] = per_joint_limit(
                f"max_{name}", values[0] if len(values) == 1 else values, problem.n_joints)
        except ValueError as error:
            raise ValueError(f"--max-{name}: {error}") from None
    if "max_torque" in limits:
        if problem.arm.masses is None:
            raise ValueError(f"--max-torque: the arm of scenario {problem.name!r} has no link "
                             "masses ([arm] masses in the scenario file)")
        from jaxarm.trajectory import check_static_load

        try:
            check_static_load(problem, limits["max_torque"])
        except ValueError as error:
            raise ValueError(f"--max-torque: {error}") from None
    if limits and args.duration is not None:
        raise ValueError("give --duration or --max-* limits, not both (with limits the duration "
                         "is the shortest that meets them)")
    if args.duration is not None:
        positive_scalar("--duration", args.duration)
        if args.duration < MIN_DURATION:
            raise ValueError(f"--duration must be at least {MIN_DURATION:g} s, got "
                             f"{args.duration!r}")
    if args.rate is not None:
        if not args.export:
            raise ValueError("--rate sets the samples per second of --export; give --export too")
        positive_scalar("--rate", args.rate)
    if args.export and args.duration is not None:
        _export_rows(args.duration, args.rate)
    if args.export and not limits and args.duration is None:
        raise ValueError("--export needs --duration or a --max-* limit to time the path")
    return limits


def _export_rows(duration: float, rate: float | None) -> float:
    """--rate (or its default), checked to give at most ``trajectory.MAX_ROWS`` rows."""
    from jaxarm.trajectory import sample_count

    rate = EXPORT_RATE if rate is None else rate
    try:
        sample_count(duration, rate)
    except ValueError as error:
        raise ValueError(f"--rate: {error}") from None
    return rate


def _report_trajectory(args, problem, result, limits: dict) -> None:
    """Time the best path (--duration or the shortest meeting --max-*), print, export."""
    import numpy as np

    from jaxarm.trajectory import Trajectory, min_duration

    duration = args.duration if args.duration is not None else min_duration(
        problem, result.best_x, **limits, allow_colliding=True)  # warned about below
    if not duration > 0:
        raise ValueError("the best path does not move: there is no trajectory to time")
    trajectory = Trajectory(problem, result.best_x, duration)
    how = ("given" if args.duration is not None else "the shortest meeting "
           + ", ".join(f"{name} {np.round(v, 4).tolist()}" for name, v in limits.items()))
    print(f"trajectory: T = {duration:.6g} s ({how})")
    peaks = trajectory.peaks()
    if problem.arm.masses is not None:
        peaks["torque"] = np.abs(trajectory.torques(
            np.linspace(0.0, duration, 2001))).max(axis=0)
    for name, values in peaks.items():
        where = " (over 2001 times)" if name == "torque" else ""
        print(f"  peak |{name}| {np.round(values, 4).tolist()} {LIMIT_UNITS[name]}{where}")
    if not result.feasible:
        print("jaxarm: warning: the best path is not collision-free", file=sys.stderr)
    if args.export:
        export = (trajectory.to_json if args.export.suffix.lower() == ".json"
                  else trajectory.to_csv)  # .csv or .csv.gz
        rate = _export_rows(duration, args.rate)
        _write(args.export, lambda path: export(path, rate=rate))


def _solve(args) -> None:
    _check_outputs(args)
    _check_settings(args)
    from jaxarm.optim.methods import parse_method

    if args.method is not None:  # checked before the scenario is loaded
        _as_flag("--method", parse_method, args.method, args.constraint)
        if args.improve and args.time_limit is None:
            raise ValueError(f"--improve needs --time-limit with --method {args.method} (a "
                             "named method runs once without one)")
    problem = _load(args)
    limits = _timing_limits(args, problem)
    from jaxarm import plot
    from jaxarm.io.runs import run_record
    from jaxarm.escalation import at_degree
    from jaxarm.io.scenario_files import obstacle_names
    from jaxarm.search import solve

    settings = dict(n_particles=args.particles, n_iters=args.iters, n_restarts=args.restarts,
                    seed=args.seed, constraint=args.constraint,
                    refine={None: False, "best": True, "all": "all"}[args.refine],
                    time_limit=args.time_limit, improve=args.improve)
    progress = False if args.quiet else (
        lambda stage: print(f"jaxarm: {stage.line()}", file=sys.stderr, flush=True))
    result = solve(problem, args.method, progress=progress, **settings)
    print(f"{problem.name}: {result.n_restarts} restart(s) x {args.particles} particles x "
          f"{args.iters} iterations")
    names = obstacle_names(args.scenario) if result.witness is not None else None
    print(result.summary(flags=True, obstacle_names=names))
    if args.json:  # solve(problem, method, **settings) repeats it (method null: the default),
        # from the problem as searched, whatever degree the best path was found at
        record = json.dumps(run_record(problem, args.method, settings, result), indent=2,
                            allow_nan=False)
        _write(args.json, lambda path: path.write_text(record, encoding="utf-8"))
    problem = at_degree(problem, result.degree)  # the degree the best path has
    if args.plot:
        figure = plot.plot_motion(problem, result.best_x)
        _write(args.plot, lambda path: figure.savefig(path, dpi=110))
    if args.gif:
        _write(args.gif, lambda path: plot.animate(problem, result.best_x, path))
    if limits or args.duration is not None:
        _report_trajectory(args, problem, result, limits)


def _study(args) -> None:
    _check_outputs(args)
    _check_settings(args)
    if args.checkpoint is not None:
        from jaxarm.io.files import output_folder

        output_folder("--checkpoint", args.checkpoint)
        if os.environ.get("JAXARM_DISTRIBUTED") == "1" or args.coordinator is not None:
            raise ValueError("--checkpoint works in one process: run the study without "
                             "--coordinator (or JAXARM_DISTRIBUTED)")
    methods = split_methods(args.methods)
    if not all(methods):
        raise ValueError(f"--methods must be comma-separated names such as A,B:feasibility, "
                         f"got {args.methods!r}")
    problem = _load(args)
    from jaxarm import plot
    from jaxarm.optim.methods import parse_methods
    from jaxarm.study import escape_study

    constraint = args.constraint or "death"
    _as_flag("--methods", parse_methods, methods, constraint)  # before any compilation
    result = escape_study(problem, methods, n_restarts=args.restarts, n_iters=args.iters,
                          n_particles=args.particles, constraint=constraint, seed=args.seed,
                          chunk_size=args.chunk_size, checkpoint=args.checkpoint)
    print(f"{problem.name}: {args.restarts} restarts x {args.particles} particles x {args.iters} "
          f"iterations, {problem.collision} collision check")
    print(result.table(pairwise=args.pairwise))
    for path, text in ((args.json, result.to_json), (args.csv, result.to_csv)):
        if path:
            _write(path, lambda temporary: temporary.write_text(text(), encoding="utf-8"))
    if args.plot:
        figure = plot.plot_escape_rates(result)
        _write(args.plot, lambda path: figure.savefig(path, dpi=110))


def _reproduce(args) -> None:
    from jaxarm.io.files import output_folder
    from jaxarm.io.scenario_files import ScenarioError, load_scenario
    from jaxarm.paper.report import reproduce_paper

    output_folder("--out", args.out)
    suite = None if args.suite is None else [name.strip() for name in args.suite.split(",")]
    if suite is not None and not all(suite):
        raise ValueError(f"--suite must be comma-separated scenario names, got {args.suite!r}")
    if suite is not None and len(set(suite)) < len(suite):
        raise ValueError(f"--suite must not repeat a scenario, got {args.suite!r}")
    for name in suite or ():
        try:
            load_scenario(name)
        except ScenarioError as error:
            raise ValueError(f"--suite: {error}") from None
    if args.quick and suite is None and args.suite_restarts is not None:
        raise ValueError(f"--suite-restarts {args.suite_restarts} needs --suite: a quick report "
                         "runs no suite unless --suite names its scenarios")
    reproduce_paper(args.out, quick=args.quick, n_restarts=args.restarts, suite=suite,
                    suite_restarts=args.suite_restarts, degrees=args.degrees, workers=args.workers)


COMMANDS = {"scenarios": _scenarios, "solve": _solve, "study": _study,
            "clutter": _clutter, "reproduce-paper": _reproduce}


def _join_processes(args) -> bool:
    """Start ``jax.distributed`` when asked; True if this process prints and writes files."""
    explicit = (args.coordinator, args.num_processes, args.process_id)
    if not any(v is not None for v in explicit):
        if os.environ.get("JAXARM_DISTRIBUTED") != "1":
            return True
    elif any(v is None for v in explicit):
        raise ValueError("--coordinator, --num-processes and --process-id go together, got "
                         f"{args.coordinator!r}, {args.num_processes!r}, {args.process_id!r}")
    elif not 0 <= args.process_id < args.num_processes:
        raise ValueError(f"--process-id must be in [0, {args.num_processes}), "
                         f"got {args.process_id}")
    import jax

    jax.config.update("jax_cpu_collectives_implementation", "gloo")  # collectives on CPU
    try:
        jax.distributed.initialize(coordinator_address=args.coordinator,
                                   num_processes=args.num_processes, process_id=args.process_id)
    except RuntimeError as error:
        raise ValueError(f"cannot join the other processes: {error}") from None
    return jax.process_index() == 0


@contextlib.contextmanager
def _compile_notices(quiet: bool, command: str):
    """Say on stderr when one of jaxarm's programs compiles (``jaxarm._compile.timing``): a
    first call can take minutes, and should not be a silent one; and, for ``study``, how far
    it is when no progress bar shows (``jaxarm.study``; the report logs its own sections).
    The loggers are as they were after the command (``main`` may be called in a notebook's
    or a test's process)."""
    names = ("jaxarm.compile", "jaxarm.study") if command == "study" else ("jaxarm.compile",)
    loggers = [logging.getLogger(name) for name in names]
    levels, handler = [logger.level for logger in loggers], _Stderr()
    for logger in loggers:
        logger.setLevel(logging.WARNING if quiet else logging.INFO)
        logger.addHandler(handler)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.removeHandler(handler)
            logger.setLevel(level)


class _Stderr(logging.Handler):
    """Writes to whatever ``sys.stderr`` is at the time (a test may have replaced it)."""

    def emit(self, record: logging.LogRecord) -> None:
        print(f"jaxarm: {record.getMessage()}", file=sys.stderr, flush=True)


def _run(args) -> None:
    with _compile_notices(args.quiet, args.command):
        _run_command(args)


def _run_command(args) -> None:
    if not args.no_cache:
        from jaxarm._compile.cache import enable_compilation_cache

        try:
            enable_compilation_cache()
        except ValueError as error:  # an unwritable cache slows the command, nothing more
            print(f"jaxarm: warning: no compilation cache: {error}", file=sys.stderr)
    if _join_processes(args):
        COMMANDS[args.command](args)
        return
    for name in ("json", "csv", "plot", "gif", "export"):  # only process 0 writes
        if hasattr(args, name):
            setattr(args, name, None)
    with tempfile.TemporaryDirectory() as scratch, contextlib.redirect_stdout(io.StringIO()):
        if args.command == "reproduce-paper":
            args.out = pathlib.Path(scratch)
        COMMANDS[args.command](args)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        _run(args)
    except BrokenPipeError:  # what reads the output stopped (``| head``): stop quietly, as
        # Unix tools do, with the status of a process SIGPIPE ended; stdout to /dev/null so that
        # Python's own flush at exit does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return _leave(141)
    except (ValueError, OSError) as error:
        if args.debug:
            raise
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        print(f"jaxarm: error: {message}", file=sys.stderr)
        return _leave(EXIT_ERROR)
    except KeyboardInterrupt:
        resume = (f"; the finished chunks are saved in {str(args.checkpoint)!r}: the same "
                  "command resumes from them" if getattr(args, "checkpoint", None) else "")
        print(f"jaxarm: interrupted{resume}", file=sys.stderr)
        return _leave(130)
    return 0


def _leave(code: int) -> int:
    """``code``; but where the report's section threads still run (an error or Ctrl-C stopped
    the report midway), the process ends at once: an exiting Python tears down the XLA runtime
    under them, and the process then aborts instead of returning ``code``."""
    reproduce = sys.modules.get("jaxarm.paper.report")  # imported only by reproduce-paper
    if reproduce is not None and reproduce.sections_running():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
