"""Input checks shared by the public constructors: every error names the field and the value."""

from __future__ import annotations

import numpy as np

from jaxarm.choices import CONSTRAINTS, one_of


def finite_vector(field: str, value, length: int | None = None) -> np.ndarray:
    """``value`` as a 1-D float64 array of finite numbers.

    Args:
      field: the name used in error messages, e.g. ``"start"``.
      value: a sequence of numbers.
      length: the required length, or None for any.

    Raises:
      ValueError: naming ``field`` and the offending value.
    """
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a sequence of numbers, got {value!r}") from None
    if array.ndim != 1:
        raise ValueError(f"{field} must be one-dimensional, got shape {array.shape}: {value!r}")
    if length is not None and array.size != length:
        raise ValueError(f"{field} must have {length} values, got {array.size}: {value!r}")
    bad = ~np.isfinite(array)
    if bad.any():
        index = int(np.argmax(bad))
        raise ValueError(f"{field}[{index}] must be finite, got {float(array[index])!r}")
    return array


def finite_scalar(field: str, value) -> float:
    """``value`` as a finite float, or a ValueError naming ``field``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a number, got {value!r}") from None
    if not np.isfinite(number):
        raise ValueError(f"{field} must be finite, got {value!r}")
    return number


def positive_scalar(field: str, value) -> float:
    """``value`` as a finite float > 0, or a ValueError naming ``field``."""
    number = finite_scalar(field, value)
    if number <= 0:
        raise ValueError(f"{field} must be > 0, got {value!r}")
    return number


def positive_int(field: str, value, minimum: int = 1, maximum: int | None = None) -> int:
    """``value`` as an int in [``minimum``, ``maximum``], or a ValueError naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{field} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{field} must be >= {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{field} must be <= {maximum}, got {value!r}")
    return int(value)


def check_seed(value) -> int:
    """``value`` as an int in [0, 2**31) (a JAX int32 key seed), or a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (
        0 <= value < 2**31
    ):
        raise ValueError(f"seed must be an integer in [0, 2**31), got {value!r}")
    return int(value)


def check_search(*, n_particles, n_iters, seed: int, constraint: str) -> None:
    """The arguments every search shares (``solve`` and studies), or a ValueError naming one."""
    positive_int("n_particles", n_particles, minimum=2)  # one particle has no one to follow
    positive_int("n_iters", n_iters)
    check_seed(seed)
    one_of("constraint", constraint, CONSTRAINTS)


def joint_limit_pairs(value, n_joints: int) -> tuple[tuple[float, float], ...]:
    """``value`` as one ``(low, high)`` pair per joint (rad), or a ValueError naming it."""
    try:
        pairs = [tuple(pair) for pair in value]
    except TypeError:
        raise ValueError(f"joint_limits must be a list of (low, high) pairs, got {value!r}"
                         ) from None
    if len(pairs) != n_joints:
        raise ValueError(f"joint_limits must have one (low, high) pair per joint ({n_joints}), "
                         f"got {len(pairs)}: {value!r}")
    out = []
    for joint, pair in enumerate(pairs):
        low, high = (float(v) for v in finite_vector(f"joint_limits[{joint}]", pair, 2))
        if not low < high:
            raise ValueError(f"joint_limits[{joint}] must have low < high, "
                             f"got ({low!r}, {high!r})")
        out.append((low, high))
    return tuple(out)


def angles_outside(limits, angles) -> list[tuple[int, float]]:
    """``(joint, angle)`` for every angle outside its range; ``angles`` shape (n_joints,)."""
    return [(joint, float(angle)) for joint, (angle, (low, high))
            in enumerate(zip(angles, limits)) if not low <= angle <= high]
