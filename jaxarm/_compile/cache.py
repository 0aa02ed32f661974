"""A persistent compilation cache: a new process reuses the programs an earlier one compiled.

XLA programs (the search, the certified check, refine) take seconds to compile; JAX can keep
them on disk (``jax_compilation_cache_dir``). The ``jaxarm`` command turns this on by default
(``--no-cache`` turns it off); from Python, call ``jaxarm.enable_compilation_cache()`` once,
before the first computation.

Where: ``$JAXARM_CACHE_DIR`` if set (``off``, ``0`` or empty: no cache), else the user's cache
directory (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux, ``~/Library/Caches`` on macOS,
``%LOCALAPPDATA%`` on Windows), under ``jaxarm/xla``. A cached program is the same program,
so results are bit-identical with or without the cache. The same call also keeps jaxarm's
traced programs in ``traces/`` there (``jaxarm._compile.stored_programs``), so a new process skips tracing too.
"""

from __future__ import annotations

import os
import pathlib
import sys

OFF = ("", "0", "off", "none", "false")
# Programs that compile faster than this are not written (XLA's tiny helper programs).
MIN_COMPILE_SECONDS = 0.05


def cache_dir() -> pathlib.Path | None:
    """Where the cache lives by default, or None when ``$JAXARM_CACHE_DIR`` switches it off."""
    chosen = os.environ.get("JAXARM_CACHE_DIR")
    if chosen is not None:
        return None if chosen.strip().lower() in OFF else pathlib.Path(chosen).expanduser()
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        base = pathlib.Path(os.environ["LOCALAPPDATA"])
    elif sys.platform == "darwin":
        base = pathlib.Path.home() / "Library" / "Caches"
    else:
        base = pathlib.Path(os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache")
    return base / "jaxarm" / "xla"


def enable_compilation_cache(path: str | os.PathLike | None = None) -> pathlib.Path | None:
    """Keep compiled programs in ``path`` (default: ``cache_dir()``) for later processes, and
    jaxarm's traced programs in ``path / "traces"`` (``jaxarm._compile.stored_programs``).

    Args:
      path: a directory (created if missing), or None for the default.

    Returns:
      The directory in use, or None when ``$JAXARM_CACHE_DIR`` switched the cache off and no
      path was given.

    Raises:
      ValueError: the directory cannot be created (naming it).
    """
    target = pathlib.Path(path).expanduser() if path is not None else cache_dir()
    if target is None:
        return None
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"compilation cache directory {str(target)!r}: "
                         f"{error.strerror}") from None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(target))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    from jaxarm._compile import stored_programs

    stored_programs.keep_in(target / "traces")
    return target
