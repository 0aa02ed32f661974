"""Study checkpoints: every finished chunk of an escape study saved in a folder, so that the
same call, run again, resumes where an interrupted one stopped and ends with the same bits.

The folder holds ``study.json``, what the study is (the problem as a scenario table, the
methods, the swarm size, iterations and base seed, and the jaxarm and jax versions and the
backend that ran it), and one ``.npz`` file per finished chunk: one method's
``RestartOutcome`` arrays for restarts [start, stop), and the chunk's seconds. A restart's
result does not depend on the chunking, so a resumed study may use another chunk size or ask
for more (or fewer) restarts: it takes each method's saved restarts 0, 1, ... up to the first
gap and runs the rest. A checkpoint of another study is refused, naming what differs.
"""

from __future__ import annotations

import json
import os
import pathlib
import re
import zipfile
from typing import NamedTuple, Sequence

import jax
import numpy as np

from jaxarm import __version__
from jaxarm.io.files import output_folder, written
from jaxarm.io.scenario_files import scenario_table
from jaxarm.model.problem import Problem
from jaxarm.optim.custom import CustomConfig
from jaxarm.optim.methods import Variant
from jaxarm.optim.restarts import RestartOutcome

MANIFEST = "study.json"
FORMAT = "jaxarm study checkpoint 1"
_CHUNK_NAME = re.compile(r"method(\d+)-restarts(\d+)-(\d+)\.npz")


class SavedRestarts(NamedTuple):
    """A method's saved restarts 0 .. ``count`` - 1, and the seconds they took."""

    outcome: RestartOutcome | None  # NumPy arrays with leading axis ``count``; None if none
    count: int
    seconds: float  # wall time of the chunks that ran them, compilation included
    compile_seconds: float  # of which compiling


def study_identity(problem: Problem, variants: Sequence[Variant], *, n_particles: int,
                   n_iters: int, seed: int) -> dict:
    """What makes two studies' restarts the same bits, as JSON data: the problem, each
    method (its label, constraint rule and settings; a user's optimiser by its type and,
    when it is a value type such as a NamedTuple, its fields), the swarm size, the
    iterations, the base seed, and the versions and backend that compute them."""
    return {
        "problem": scenario_table(problem),
        "methods": [{"label": v.label, "constraint": v.constraint, "config": _describe(v.config)}
                    for v in variants],
        "n_particles": n_particles,
        "n_iters": n_iters,
        "seed": seed,
        "versions": {"jaxarm": __version__, "jax": jax.__version__,
                     "backend": jax.default_backend()},
    }


def _describe(config) -> str:
    if not isinstance(config, CustomConfig):
        return repr(config)  # PSOConfig, StrategyConfig: NamedTuples of exact numbers
    optimizer = config.optimizer
    kind = f"{type(optimizer).__module__}.{type(optimizer).__qualname__}"
    try:
        hash(optimizer)
    except TypeError:  # compared by identity: only its type and label can be recognised
        return kind
    return f"{kind} {optimizer!r}" if type(optimizer).__repr__ is not object.__repr__ else kind


class StudyCheckpoint:
    """A checkpoint folder open for one study (``open``): ``saved`` reads, ``save`` writes."""

    def __init__(self, folder: pathlib.Path):
        self.folder = folder

    @classmethod
    def open(cls, folder, identity: dict) -> StudyCheckpoint:
        """The checkpoint in ``folder`` for the study ``identity`` (``study_identity``),
        created with its parents if need be.

        Raises:
          ValueError: naming the folder: not writable, not a checkpoint, or the checkpoint of
            another study (naming what differs).
        """
        if not isinstance(folder, (str, os.PathLike)) or not os.fspath(folder):
            raise ValueError(f"checkpoint must be a folder's path, got {folder!r}")
        folder = output_folder("checkpoint", folder)
        manifest = folder / MANIFEST
        if manifest.is_file():
            _check_same_study(folder, _read_manifest(manifest), identity)
        elif folder.is_dir() and any(folder.iterdir()):
            raise ValueError(f"checkpoint {str(folder)!r} holds files but no {MANIFEST}: not a "
                             "study checkpoint; give an empty or new folder")
        else:
            try:
                folder.mkdir(parents=True, exist_ok=True)
                with written(manifest) as temporary:
                    temporary.write_text(json.dumps({"format": FORMAT, "study": identity},
                                                    indent=2), encoding="utf-8")
            except OSError as error:
                raise ValueError(f"checkpoint {str(folder)!r}: cannot write there: "
                                 f"{error.strerror or error}") from None
        return cls(folder)

    def saved(self, method: int, n_restarts: int) -> SavedRestarts:
        """Method ``method``'s saved restarts from 0 up to the first gap, at most
        ``n_restarts`` of them."""
        chunks = sorted((int(start), int(stop), path) for path in self.folder.iterdir()
                        if (match := _CHUNK_NAME.fullmatch(path.name))
                        and int(match[1]) == method
                        for start, stop in [match.group(2, 3)])
        parts, count, seconds, compiling = [], 0, 0.0, 0.0
        for start, stop, path in chunks:
            if not start <= count < stop or count >= n_restarts:
                continue
            outcome, chunk_seconds, chunk_compiling = self._read(path, stop - start)
            keep = slice(count - start, min(stop, n_restarts) - start)
            parts.append(RestartOutcome(*(field[keep] for field in outcome)))
            count = min(stop, n_restarts)
            seconds, compiling = seconds + chunk_seconds, compiling + chunk_compiling
        outcome = parts[0].concatenate(*parts[1:]) if parts else None
        return SavedRestarts(outcome, count, seconds, compiling)

    def save(self, method: int, start: int, outcome: RestartOutcome, seconds: float,
             compile_seconds: float) -> None:
        """Save method ``method``'s restarts ``start`` .. ``start + len(outcome) - 1``
        (written whole or not at all)."""
        stop = start + len(outcome.best_fitness)
        path = self.folder / f"method{method}-restarts{start:07d}-{stop:07d}.npz"
        with written(path) as temporary:
            np.savez(temporary, **{name: np.asarray(field)
                                   for name, field in outcome._asdict().items()},
                     seconds=seconds, compile_seconds=compile_seconds)

    def _read(self, path: pathlib.Path, count: int) -> tuple[RestartOutcome, float, float]:
        try:
            with open(path, "rb") as handle, np.load(handle) as data:  # closed if it fails
                outcome = RestartOutcome(*(data[name] for name in RestartOutcome._fields))
                seconds, compiling = float(data["seconds"]), float(data["compile_seconds"])
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
            raise ValueError(f"checkpoint {str(self.folder)!r}: cannot read {path.name}: "
                             f"{error}; remove that file to run its restarts again") from None
        if any(len(field) != count for field in outcome):
            raise ValueError(f"checkpoint {str(self.folder)!r}: {path.name} does not hold "
                             f"{count} restarts; remove it to run them again")
        return outcome, seconds, compiling


def _read_manifest(path: pathlib.Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ValueError(f"checkpoint {str(path.parent)!r}: cannot read {MANIFEST}: "
                         f"{error}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or "study" not in data:
        raise ValueError(f"checkpoint {str(path.parent)!r}: {MANIFEST} is not a jaxarm study "
                         "checkpoint of this version")
    return data["study"]


def _check_same_study(folder: pathlib.Path, saved: dict, identity: dict) -> None:
    """A ValueError naming the first thing that differs between the two studies."""
    identity = json.loads(json.dumps(identity))  # as read back: tuples become lists
    labels = lambda study: ",".join(m["label"] for m in study["methods"])  # noqa: E731
    versions = lambda study: ", ".join(f"{k} {v}" for k, v in study["versions"].items())  # noqa
    checks = [  # (what differs, its value in a study, whether to show the two values)
        ("problem", lambda study: study["problem"]["name"], True),
        ("another version of the problem of that name", lambda study: study["problem"], False),
        ("methods", labels, True),
        ("the same methods with other settings", lambda study: study["methods"], False),
        ("base seed", lambda study: study["seed"], True),
        ("swarm size", lambda study: study["n_particles"], True),
        ("iterations", lambda study: study["n_iters"], True),
        ("versions", versions, True),
    ]
    for what, value, show in checks:
        try:
            then = value(saved)
        except (KeyError, TypeError):
            then = None
        now = value(identity)
        if then != now:
            what = f"{what} {then!r}, not {now!r}" if show else what
            raise ValueError(f"checkpoint {str(folder)!r} was written for {what}: give "
                             "another folder, or remove this one to start again")
