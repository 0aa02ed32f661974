"""How jaxarm compiles its programs: ``jit`` is ``jax.jit`` with faster compilation on CPU.

A short run spends most of its time in XLA compiling the search, the certified check and
refine. On CPU jaxarm compiles them with ``CPU_COMPILER_OPTIONS``: LLVM's optimisation level 1
instead of XLA's default 2: programs compile faster and run as fast, PSO results are
bit-identical, and the evosax CMA-ES restarts differ in their last bits
(``benchmarks/RESULTS.md``, *Decisions and negative results*, "One copy of the check per
program, and LLVM optimisation level 1"). A program whose run outweighs its compilation can
be compiled at XLA's default level instead, call by call, by a static boolean argument that
its caller sets (``level_flag``). Other backends keep XLA's defaults (untested there).
"""

from __future__ import annotations

import functools
import threading

import jax

from jaxarm._compile import stored_programs, timing

CPU_COMPILER_OPTIONS = {"xla_backend_optimization_level": 1}


def jit(fun=None, *, storable: bool = False, level_flag: str | None = None,
        label: str | None = None, **options):
    """``jax.jit(fun, **options)``, compiled with ``CPU_COMPILER_OPTIONS`` when JAX runs on CPU.

    The backend is read at the first call (so after ``jax.distributed.initialize()``, which must
    come before it). Called inside another trace (a caller's ``jax.jit``, ``vmap`` or ``grad``),
    it is a plain ``jax.jit``: XLA takes compiler options from the outermost program only. The
    result forwards ``trace``, ``lower`` and the other attributes of the top-level ``jax.jit``.
    Usable as ``functools.partial(jit, static_argnums=0)`` on a function.

    ``storable=True`` lets ``jaxarm._compile.stored_programs`` keep the traced program on disk: only for a
    module-level function whose trace depends on nothing but its arguments and jaxarm's source
    as written (not a closure over values made at run time).

    ``level_flag`` names a static boolean argument of ``fun`` (it must be in
    ``static_argnames``): calls that set it true compile at XLA's default optimisation level
    instead (on CPU; elsewhere nothing changes), for programs whose run costs far more than
    their compilation. The caller decides; this layer knows nothing of what the program holds.
    ``lower`` and ``trace`` choose by their arguments as calls do; other attributes of the
    ``jax.jit`` are those of its ``CPU_COMPILER_OPTIONS`` program.

    ``label`` (what users would call the program, "the search"): the ``jaxarm.compile`` logger
    says when it starts and ends compiling (``jaxarm._compile.timing``).
    """
    if fun is None:
        return functools.partial(jit, storable=storable, level_flag=level_flag, label=label,
                                 **options)
    if label is not None:
        timing.announce(fun.__name__, label)
    return _Program(fun, options, storable, level_flag)


try:  # JAX's own test for "outside any trace" (private: JAX exports none)
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:  # pragma: no cover
    _trace_state_clean = None


def rank_promotion_allowed(function):
    """``function`` traced with NumPy's rank promotion allowed, whatever the caller's
    ``jax_numpy_rank_promotion`` (jaxarm's tests raise on it): for code that broadcasts arrays
    of different ranks on purpose (``jaxarm.model.world``'s polygon kernels, evosax's strategies)."""
    @functools.wraps(function)
    def promoting(*args, **kwargs):
        with jax.numpy_rank_promotion("allow"):
            return function(*args, **kwargs)
    return promoting


def _at_top_level(args) -> bool:
    """Whether a call with these arguments is outside any trace."""
    if _trace_state_clean is None:  # a JAX without it: tracer arguments are the usual sign
        return not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(args))
    return _trace_state_clean()


class _TraceCounter:
    """How many times a function was traced: ``counting(fun)`` is ``fun`` counting its calls
    (thread-safe; kept apart from ``_Program`` so that the wrapper jax.jit holds does not hold
    the program too)."""

    def __init__(self):
        self.count = 0
        self._lock = threading.Lock()

    def counting(self, fun):
        @functools.wraps(fun)
        def counted(*args, **kwargs):
            with self._lock:
                self.count += 1
            return fun(*args, **kwargs)
        return counted


class _Program:
    """A ``jax.jit`` made at its first use, for the backend in use then; with
    ``jaxarm._compile.stored_programs`` on, top-level calls go through stored traced programs instead.

    Safe to call from several threads: a program is made once."""

    def __init__(self, fun, options: dict, storable: bool = False,
                 level_flag: str | None = None):
        self._fun, self._options, self._storable = fun, options, storable
        self._level_flag = level_flag
        if level_flag is not None and level_flag not in self._static_names:
            raise ValueError(f"level_flag {level_flag!r} must name a static argument of "
                             f"{fun.__name__}, one of {sorted(self._static_names)}")
        self._jitted = {}  # at the default level (bool) -> jax.jit
        self._nested = jax.jit(fun, **options)
        self._stored = {}  # Call.memo_key() -> stored_programs.Stored, or None where export refused it
        self._lock = threading.Lock()  # held while _jitted or a stored program is made
        self._traces = _TraceCounter()
        self._counted = self._traces.counting(fun)  # what the top-level jax.jit traces
        functools.update_wrapper(self, fun)

    def _at_default_level(self, statics: dict | None) -> bool:
        """Whether a call with these static arguments (None: unknown) compiles at XLA's default
        level."""
        return (jax.default_backend() != "cpu"
                or (statics is not None and self._level_flag is not None
                    and bool(statics.get(self._level_flag, False))))

    def _compiler_options(self, statics: dict | None):
        return None if self._at_default_level(statics) else CPU_COMPILER_OPTIONS

    def _compiled(self, statics: dict | None = None):
        """The top-level ``jax.jit`` for calls with these static arguments."""
        at_default = self._at_default_level(statics)
        with self._lock:
            if at_default not in self._jitted:
                self._jitted[at_default] = jax.jit(
                    self._counted, compiler_options=None if at_default else CPU_COMPILER_OPTIONS,
                    **self._options)
            return self._jitted[at_default]

    def _statics(self, args, kwargs) -> dict | None:
        """The static arguments of a call, by name (None when nothing chooses by them)."""
        if self._level_flag is None:
            return None
        bound = stored_programs.signature(self._fun).bind(*args, **kwargs)
        return {name: value for name, value in bound.arguments.items()
                if name in self._static_names}

    def lower(self, *args, **kwargs):
        return self._compiled(self._statics(args, kwargs)).lower(*args, **kwargs)

    def trace(self, *args, **kwargs):
        return self._compiled(self._statics(args, kwargs)).trace(*args, **kwargs)

    @functools.cached_property
    def _static_names(self) -> frozenset:
        names = list(stored_programs.signature(self._fun).parameters)
        numbers = self._options.get("static_argnums", ())
        numbers = (numbers,) if isinstance(numbers, int) else numbers
        named = self._options.get("static_argnames", ())
        named = (named,) if isinstance(named, str) else named
        return frozenset([names[i] for i in numbers] + list(named))

    def __call__(self, *args, **kwargs):
        if not _at_top_level((args, kwargs)):
            return self._nested(*args, **kwargs)
        call = (stored_programs.split_call(self._fun, self._static_names, args, kwargs)
                if self._storable and stored_programs.usable() else None)
        if call is None or (stored := self._stored_program(call)) is None:  # export refused it
            return self._compiled(self._statics(args, kwargs))(*args, **kwargs)
        return jax.tree.unflatten(stored.out_tree, stored.call(*call.leaves))

    def _stored_program(self, call: stored_programs.Call) -> stored_programs.Stored | None:
        """The stored program for ``call``, made by the first thread that asks for it (one lock
        for all calls: tracing runs in Python, one thread at a time, anyway)."""
        key = call.memo_key()
        with self._lock:
            if key not in self._stored:
                label = f"{self._fun.__module__}.{self._fun.__qualname__} {self._options!r}"
                self._stored[key] = stored_programs.stored_program(
                    self._fun, label, call, self._compiler_options(dict(call.statics)))
            return self._stored[key]

    def programs_made(self) -> int:
        """How many top-level programs this function has made so far, in this process.

        The number of times the top-level ``jax.jit`` has traced the function (a call, or a
        ``lower`` or ``trace`` through this object, with static arguments, shapes or dtypes it
        has not traced yet, or after ``jax.clear_caches()``), plus one per stored program made
        or loaded by ``jaxarm._compile.stored_programs`` (a program ``jax.export`` refused is
        not one: its calls go to the ``jax.jit`` and are counted there). Calls inside a caller's
        trace use a plain ``jax.jit`` of their own and are not counted. The count is this
        object's own: a ``jit`` made elsewhere around the same function has its own count. It
        only grows.

        Why: tests and benchmarks assert how many programs a run compiles ("a second batch
        size of the same padded size makes no new program") without reading JAX's private
        attributes (``jax.jit``'s ``_cache_size()``). The trace is counted by a wrapper around
        the Python function (``functools.wraps``, so signatures and ``static_argnames`` resolve
        as before), which changes nothing in the traced program or its results."""
        with self._lock:
            stored = sum(s is not None for s in self._stored.values())
        return self._traces.count + stored

    def __getattr__(self, name: str):  # eval_shape, clear_cache, ...
        if name.startswith("__") or name in ("_fun", "_options", "_jitted", "_nested", "_stored",
                                             "_storable", "_lock", "_traces", "_counted",
                                             "_level_flag"):
            raise AttributeError(name)
        return getattr(self._compiled(), name)
