"""Saved runs: a ``solve`` call as ``jaxarm solve --json`` writes it (problem, method,
settings, ``Result``, versions), and ``load_run`` that reads one back to repeat it."""

from __future__ import annotations

import json
import pathlib
from typing import NamedTuple

import jax

from jaxarm import __version__
from jaxarm.io.scenario_files import problem_from_table, scenario_table
from jaxarm.model.problem import Problem
from jaxarm.search import Result


class SavedRun(NamedTuple):
    """A ``solve`` call as ``jaxarm solve --json`` saves it: ``solve(problem, method,
    **settings)`` repeats it, restart for restart."""

    problem: Problem
    method: str | None  # None: solve's default search
    settings: dict  # solve's keyword arguments: n_particles, n_iters, n_restarts, seed, ...
    result: Result
    versions: dict  # {"jaxarm": ..., "jax": ...} that produced it


def run_record(problem: Problem, method: str | None, settings: dict, result: Result) -> dict:
    """What ``solve --json`` writes: the problem as a scenario table, the method, ``solve``'s
    keyword arguments, the ``Result`` and the jaxarm and jax versions.

    The settings repeat the stages that ran rather than the time they had (``max_stages``,
    no time limit): the same stages on any machine, so the same result bit for bit; the
    time limit asked for stays in the result (``Result.time_limit``)."""
    settings = dict(settings)
    if result.stages:
        settings.update(time_limit=None, max_stages=len(result.stages))
    return {"jaxarm": __version__, "jax": jax.__version__, "scenario": problem.name,
            "problem": scenario_table(problem), "method": method, "settings": settings,
            "result": result.to_dict()}


def load_run(path: str | pathlib.Path) -> SavedRun:
    """The run that ``jaxarm solve --json path`` saved (see ``run_record``).

    Raises:
      ValueError: naming the file: unreadable, not JSON, or not such a record.
    """
    try:
        data = json.loads(pathlib.Path(path).read_text(encoding="utf-8"))
    except OSError as error:
        raise ValueError(f"cannot read {str(path)!r}: {error.strerror or error}") from None
    except ValueError as error:  # JSONDecodeError, UnicodeDecodeError
        raise ValueError(f"{path} is not a solve --json record: not JSON ({error})") from None
    missing = {"problem", "method", "settings", "result"} - set(data if isinstance(data, dict)
                                                                 else ())
    if missing:
        raise ValueError(f"{path} is not a solve --json record: no {sorted(missing)}")
    try:
        return SavedRun(problem=problem_from_table(data["problem"]), method=data["method"],
                        settings=data["settings"], result=Result.from_dict(data["result"]),
                        versions={"jaxarm": data.get("jaxarm"), "jax": data.get("jax")})
    except (ValueError, TypeError, KeyError) as error:
        raise ValueError(f"{path}: not a valid solve --json record: {error}") from None
