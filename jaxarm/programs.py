"""How jaxarm compiles its programs: ``jit`` is ``jax.jit`` with faster compilation on CPU.

A short run spends most of its time in XLA compiling the search, the certified check and
refine. On CPU jaxarm compiles them with ``CPU_COMPILER_OPTIONS``: LLVM's optimisation level 1
instead of XLA's default 2. Measured on this project's 2-core CPU machine
(``benchmarks/RESULTS.md``, "One copy of the check per program, and LLVM optimisation level 1";
the certified search on paper-case-1: 5.8 s -> 3.9 s, by hand), programs compile faster and
run as fast, and PSO results are bit-identical; the evosax CMA-ES restarts differ in their last
bits. Other backends keep XLA's defaults (untested there).
"""

from __future__ import annotations

import functools

import jax

CPU_COMPILER_OPTIONS = {"xla_backend_optimization_level": 1}


def jit(fun=None, **options):
    """``jax.jit(fun, **options)``, compiled with ``CPU_COMPILER_OPTIONS`` when JAX runs on CPU.

    The backend is read at the first call (so after ``jax.distributed.initialize()``, which must
    come before it). Called inside another trace (a caller's ``jax.jit``, ``vmap`` or ``grad``),
    it is a plain ``jax.jit``: XLA takes compiler options from the outermost program only. The
    result forwards ``trace``, ``lower`` and the other attributes of the top-level ``jax.jit``.
    Usable as ``functools.partial(jit, static_argnums=0)`` on a function.
    """
    if fun is None:
        return functools.partial(jit, **options)
    return _Program(fun, options)


try:  # JAX's own test for "outside any trace" (private: JAX exports none)
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:  # pragma: no cover
    _trace_state_clean = None


def _at_top_level(args) -> bool:
    """Whether a call with these arguments is outside any trace."""
    if _trace_state_clean is None:  # a JAX without it: tracer arguments are the usual sign
        return not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(args))
    return _trace_state_clean()


class _Program:
    """A ``jax.jit`` made at its first use, for the backend in use then."""

    def __init__(self, fun, options: dict):
        self._fun, self._options, self._jitted = fun, options, None
        self._nested = jax.jit(fun, **options)
        functools.update_wrapper(self, fun)

    def _compiled(self):
        if self._jitted is None:
            extra = CPU_COMPILER_OPTIONS if jax.default_backend() == "cpu" else None
            self._jitted = jax.jit(self._fun, compiler_options=extra, **self._options)
        return self._jitted

    def __call__(self, *args, **kwargs):
        program = self._compiled() if _at_top_level((args, kwargs)) else self._nested
        return program(*args, **kwargs)

    def __getattr__(self, name: str):  # trace, lower, _cache_size, ...
        if name.startswith("__") or name in ("_fun", "_options", "_jitted", "_nested"):
            raise AttributeError(name)
        return getattr(self._compiled(), name)
