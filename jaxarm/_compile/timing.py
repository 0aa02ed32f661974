"""Time spent making programs, read from JAX's own monitoring events, and notices of it.

JAX records how long it traces a function, lowers it and compiles it (or loads it from the
persistent compilation cache), as time spans (``jax.monitoring``). ``compile_time()`` adds up
the spans of the calling thread while it is open, counting overlapping spans (a program
traced inside another's trace) once, so a caller can report compiling apart from running.
The same events tell the ``jaxarm.compile`` logger when one of jaxarm's own programs starts
and ends compiling (INFO), so that a long first call is not a silent one: the ``jaxarm``
command shows these on stderr, and a Python user sees them with
``logging.getLogger("jaxarm").setLevel("INFO")`` and a handler (``logging.basicConfig()``).
The notice comes once a program is traced, when its compiling starts. The listener is JAX's
(``jax.monitoring``): ``jax.monitoring.clear_event_listeners()`` removes it, and this module
then measures nothing.
"""

from __future__ import annotations

import contextlib
import logging
import threading

import jax

TRACE_EVENT = "/jax/core/compile/jaxpr_trace_duration"
LOWER_EVENT = "/jax/core/compile/jaxpr_to_mlir_module_duration"
COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"

logger = logging.getLogger("jaxarm.compile")
logger.addHandler(logging.NullHandler())

_state = threading.local()  # .timers: the open CompileTimers of this thread
_names: dict[str, str] = {}  # module name of a jaxarm program ("jit(search_restarts)") -> label
_lock = threading.Lock()
_listening = False


class CompileTimer:
    """Seconds this thread spent tracing, lowering and compiling while the timer was open."""

    def __init__(self):
        self._spans: list[tuple[float, float]] = []

    @property
    def seconds(self) -> float:
        """The length of the union of the spans (a nested trace counts once)."""
        total, covered = 0.0, -float("inf")
        for start, end in sorted(self._spans):
            start = max(start, covered)
            if end > start:
                total += end - start
                covered = end
        return total


@contextlib.contextmanager
def compile_time():
    """``with compile_time() as timer: ...``; then ``timer.seconds``."""
    _listen()
    timer = CompileTimer()
    timers = _state.__dict__.setdefault("timers", [])
    timers.append(timer)
    try:
        yield timer
    finally:
        timers.remove(timer)


def announce(function_name: str, label: str) -> None:
    """Log when the program made from ``function_name`` (a ``jit`` of jaxarm's) compiles."""
    with _lock:
        _names[f"jit({function_name})"] = label
    _listen()


def _listen() -> None:
    global _listening
    with _lock:  # registered before any thread goes on to compile
        if not _listening:
            jax.monitoring.register_event_time_span_listener(_on_span)
            _listening = True


def _on_span(event: str, start: float, end: float, **kwargs) -> None:
    if event not in (TRACE_EVENT, LOWER_EVENT, COMPILE_EVENT):
        return
    for timer in getattr(_state, "timers", ()):
        timer._spans.append((start, end))
    label = _names.get(kwargs.get("fun_name", ""))
    if label is None:
        return
    if event == LOWER_EVENT:  # the backend's compile (or a cache load) comes next
        logger.info("compiling %s (the first call for these sizes) ...", label)
    elif event == COMPILE_EVENT:
        logger.info("compiled %s in %.1f s", label, end - start)
