"""Traced programs kept on disk with ``jax.export``: a new process skips tracing them.

The persistent compilation cache (``jaxarm._compile.cache``) keeps XLA's output, but a new process still
traces each program in Python and lowers it to StableHLO before JAX can look it up in that
cache. For jaxarm's large programs (the search, the checks, refine) that takes up to seconds
each (the search's and the checks': ``benchmarks/RESULTS.md``, *Compiled programs in the quick
report*).
When the cache is on, jaxarm keeps every top-level program it traces as a serialized
``jax.export.Exported`` in ``traces/`` under the cache directory, and a later process calls the
stored program (``Exported.call``) instead of tracing the Python code again.

A stored program is used only when everything its trace depends on is the same: the function,
its static arguments, the shapes and dtypes of the others, jaxarm's source files, the versions
of jax, jaxlib, numpy, optax and evosax, the backend and the JAX settings that change traces
(x64, the PRNG). Changes made to jaxarm's modules at run time (a test's monkeypatch of a
constant) are not seen, as ``jax.jit``'s own cache does not see them: call
``jaxarm._compile.stored_programs.keep_in(None)`` before patching. Calls that cannot be keyed that way run as
plain ``jax.jit``: a static argument without a stable ``repr`` (a custom optax optimizer, say),
an array sharded over several devices or processes (the restarts' ids when there are several;
the other programs, on one device, are stored as with one), arguments that are not arrays or
numbers. A program runs through ``Exported.call`` whether it was just traced or loaded, so XLA
compiles the same module either way (and finds it in the compilation cache the second time). A
program ``jax.export`` refuses (a custom call it does not allow, say) runs as plain
``jax.jit``, with a warning. The files are read with ``pickle`` (the result's tree structure
beside the program): like XLA's own cache, which holds executables, the folder should be one
only you can write to.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import inspect
import os
import pathlib
import pickle
import tempfile
import warnings
from typing import Any, Callable, NamedTuple

import jax
import numpy as np
from jax import export

_directory: pathlib.Path | None = None
VERSIONED = ("jax", "jaxlib", "numpy", "optax", "evosax", "flatbuffers")
# JAX settings that change what a trace produces.
TRACE_SETTINGS = ("jax_enable_x64", "jax_default_prng_impl", "jax_threefry_partitionable",
                  "jax_default_matmul_precision", "jax_numpy_dtype_promotion",
                  "jax_numpy_rank_promotion", "jax_enable_checks")


def keep_in(directory: str | os.PathLike | None) -> None:
    """Store traced programs in ``directory`` (created when first written); None: stop."""
    global _directory
    _directory = None if directory is None else pathlib.Path(directory)


def directory() -> pathlib.Path | None:
    """Where traced programs are kept, or None when they are not."""
    return _directory


class Stored(NamedTuple):
    """A program as ``Exported.call`` under ``jax.jit``, taking and returning flat leaves."""

    call: Callable  # (*leaves) -> list of output leaves
    out_tree: Any  # PyTreeDef of the program's result


class Call(NamedTuple):
    """One call of a program, split the way its trace depends on it."""

    statics: tuple  # ((name, value), ...) for the static arguments
    leaves: list  # the other arguments' leaves
    in_tree: Any  # their PyTreeDef, over {name: value}
    avals: tuple  # ((shape, dtype name, weak_type), ...) per leaf

    def memo_key(self) -> tuple:
        return self.statics, self.in_tree, self.avals


@functools.cache
def signature(fun: Callable) -> inspect.Signature:
    """``inspect.signature(fun)``, worked out once per function (calls read it every time)."""
    return inspect.signature(fun)


def split_call(fun: Callable, static_names: frozenset, args: tuple, kwargs: dict) -> Call | None:
    """``fun(*args, **kwargs)`` as static values and array leaves, or None when it cannot be
    keyed (a static value without a stable repr, a leaf that is not an array or a number, an
    array sharded over several devices or processes)."""
    try:
        bound = signature(fun).bind(*args, **kwargs)
    except TypeError:
        return None
    statics = tuple((name, value) for name, value in bound.arguments.items()
                    if name in static_names)
    if not all(_stable(value) for _, value in statics):
        return None
    dynamic = {name: value for name, value in bound.arguments.items() if name not in static_names}
    leaves, in_tree = jax.tree.flatten(dynamic)
    avals = []
    for leaf in leaves:
        if not isinstance(leaf, (np.ndarray, np.generic, jax.Array, bool, int, float)):
            return None
        if isinstance(leaf, jax.Array) and len(leaf.sharding.device_set) != 1:
            return None  # sharded over devices or processes: traced as usual
        aval = jax.typeof(leaf)
        avals.append((tuple(aval.shape), aval.dtype.name, bool(aval.weak_type)))
    return Call(statics, leaves, in_tree, tuple(avals))


def _stable(value) -> bool:
    """Whether ``repr(value)`` names the value the same way in every process."""
    if value is None or isinstance(value, (bool, int, float, str, np.generic, np.dtype)):
        return True
    if isinstance(value, (tuple, list)):  # NamedTuples too: their repr names their class
        return all(_stable(item) for item in value)
    return False


def usable() -> bool:
    """Whether calls may go through stored programs now: a directory is set (``split_call``
    leaves sharded calls to ``jax.jit``)."""
    return _directory is not None


def stored_program(fun: Callable, label: str, call: Call, compiler_options) -> Stored | None:
    """The program for ``call``: loaded from the directory, or traced, exported and written;
    None (with a warning) when ``jax.export`` refuses it, for ``jax.jit`` to run instead."""
    path = _directory / f"{_disk_key(label, call, compiler_options)}.exported"
    loaded = _load(path)
    if loaded is not None:
        exported, out_tree = loaded
    else:
        try:
            exported, out_tree = _export(fun, call)
        except Exception as error:  # noqa: BLE001 - e.g. a custom call export does not allow
            warnings.warn(f"jaxarm: {label.split()[0]} is traced in every process: jax.export "
                          f"refused it ({type(error).__name__}: {str(error)[:200]})",
                          RuntimeWarning, stacklevel=3)
            return None
        _write(path, exported, out_tree)

    def run(*leaves):
        return exported.call(*leaves)

    # named after the function, as jax.jit names its programs (XLA's cache files, profiles)
    run.__name__ = run.__qualname__ = getattr(fun, "__name__", "program")
    return Stored(jax.jit(run, compiler_options=compiler_options), out_tree)


def _export(fun: Callable, call: Call):
    statics, in_tree = dict(call.statics), call.in_tree
    out_trees = []

    def flat(*leaves):
        bound = signature(fun).bind_partial(**statics, **jax.tree.unflatten(in_tree, leaves))
        out_leaves, out_tree = jax.tree.flatten(fun(*bound.args, **bound.kwargs))
        out_trees.append(out_tree)
        return out_leaves

    specs = [jax.ShapeDtypeStruct(shape, np.dtype(dtype), weak_type=weak)
             for shape, dtype, weak in call.avals]
    exported = export.export(jax.jit(flat))(*specs)
    return exported, out_trees[-1]


def _load(path: pathlib.Path):
    try:
        payload = path.read_bytes()
    except OSError:  # not stored yet (or unreadable): trace it
        return None
    try:
        serialized, out_tree = pickle.loads(payload)
        return export.deserialize(serialized), out_tree
    except Exception:  # noqa: BLE001 - a truncated or foreign file is traced again and replaced
        return None


def _write(path: pathlib.Path, exported, out_tree) -> None:
    payload = pickle.dumps((exported.serialize(), out_tree))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # written whole under a temporary name, then renamed: readers never see a partial file
        with tempfile.NamedTemporaryFile(dir=path.parent, delete=False, suffix=".tmp") as file:
            file.write(payload)
        os.replace(file.name, path)
    except OSError as error:
        warnings.warn(f"jaxarm: traced program not kept in {str(path.parent)!r}: "
                      f"{error.strerror}", RuntimeWarning, stacklevel=3)


def _disk_key(label: str, call: Call, compiler_options) -> str:
    material = repr((label, call.statics, str(call.in_tree), call.avals, compiler_options,
                     jax.default_backend(), _versions(), _settings(), _source()))
    return hashlib.sha256(material.encode()).hexdigest()


@functools.cache
def _versions() -> tuple:
    """The versioned packages' installed versions (read once per process)."""
    found = []
    for name in VERSIONED:
        try:
            found.append((name, importlib.metadata.version(name)))
        except importlib.metadata.PackageNotFoundError:
            found.append((name, None))
    return tuple(found)


def _settings() -> tuple:
    return tuple((name, repr(jax.config.values.get(name))) for name in TRACE_SETTINGS)


@functools.cache
def _source() -> str:
    """A hash of jaxarm's Python source files (computed once per process)."""
    digest = hashlib.sha256()
    package = pathlib.Path(__file__).parents[1]  # jaxarm/
    for file in sorted(package.rglob("*.py")):
        digest.update(str(file.relative_to(package)).encode() + b"\0" + file.read_bytes())
    return digest.hexdigest()
