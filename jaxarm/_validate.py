"""Input checks shared by the public constructors: every error names the field and the value."""

from __future__ import annotations

import re

import numpy as np

from jaxarm.choices import CONSTRAINTS, MAX_HISTORY_AT_ONCE, MAX_PATHS_AT_ONCE, one_of


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


# cm: the largest magnitude of a length, coordinate, radius, margin or tolerance. Geometry runs
# in float32, whose spacing at 1e5 cm (0.008 cm) is still finer than the certified check's
# default tolerance (0.01 cm); an arm 1e7 cm long no longer had a free motion certified, and
# past about 1e19 cm the squared distances overflow.
MAX_CM = 1e5
_FLOAT32 = np.finfo(np.float32)


def representable(field: str, value, limit: float = float(_FLOAT32.max), unit: str = ""):
    """``value`` (finite numbers: a scalar or an array) if float32, the dtype paths are computed
    in, holds every entry as it is: none of magnitude above ``limit`` (at most float32's
    largest), none nonzero below float32's smallest normal (it would become 0 or lose digits).

    Raises:
      ValueError: naming ``field`` (with an array entry's index) and the value.
    """
    array = np.asarray(value, dtype=np.float64)
    magnitude = np.abs(array)
    bad = (magnitude > limit) | ((magnitude > 0) & (magnitude < _FLOAT32.tiny))
    if bad.any():
        index = np.unravel_index(int(np.argmax(bad)), array.shape)
        name = field + "".join(f"[{i}]" for i in index)
        number = float(array[index])
        if abs(number) > limit:
            raise ValueError(f"{name} must be within +-{limit:g}{unit}, got {number!r} "
                             "(computed in float32)")
        raise ValueError(f"{name} must be 0 or at least {float(_FLOAT32.tiny):.3g}{unit} in "
                         f"magnitude, got {number!r} (float32 would make it 0)")
    return value


def renamed(message: str, names: dict[str, str]) -> str:
    """``message`` with the fields it is about spelled as the user spelled them: when it starts
    with a key of ``names`` (a ``Problem`` field such as ``"n_samples"``), every mention of a
    key becomes its value (``"search.samples"``, ``"--samples"``)."""
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, names)) + r")\b")
    first = pattern.match(message)
    return pattern.sub(lambda m: names[m.group(1)], message) if first else message


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


def check_search(*, n_particles, n_iters, seed: int, constraint: str,
                 restarts_at_once: int = 1) -> None:
    """The arguments every search shares (``solve`` and studies), or a ValueError naming one;
    ``restarts_at_once``: the restarts of one compiled call (``MAX_PATHS_AT_ONCE``)."""
    positive_int("n_particles", n_particles, minimum=2)  # one particle has no one to follow
    positive_int("n_iters", n_iters)
    check_seed(seed)
    one_of("constraint", constraint, CONSTRAINTS)
    for size, what, limit in ((n_particles, "particles", MAX_PATHS_AT_ONCE),
                              (n_iters + 1, "iterations (+1)", MAX_HISTORY_AT_ONCE)):
        if restarts_at_once * size > limit:
            raise ValueError(f"{restarts_at_once} restart(s) x {size} {what} is "
                             f"{restarts_at_once * size:.3g} at once, more than {limit} (2**"
                             f"{limit.bit_length() - 1}): give fewer restarts at once (a study's "
                             f"chunk_size) or fewer {what.split()[0]}")


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
        values = representable(f"joint_limits[{joint}]", finite_vector(f"joint_limits[{joint}]",
                                                                       pair, 2))
        low, high = (float(v) for v in values)
        if not low < high:
            raise ValueError(f"joint_limits[{joint}] must have low < high, "
                             f"got ({low!r}, {high!r})")
        out.append((low, high))
    return tuple(out)


def angles_outside(limits, angles) -> list[tuple[int, float]]:
    """``(joint, angle)`` for every angle outside its range; ``angles`` shape (n_joints,)."""
    return [(joint, float(angle)) for joint, (angle, (low, high))
            in enumerate(zip(angles, limits)) if not low <= angle <= high]
