"""A path in seconds: joint trajectories for a transfer time T (paper eqs. 8-9), their torques,
the shortest T that respects velocity, acceleration, jerk and torque limits, and export.

With r = t / T, the k-th time derivative of a joint angle is ``theta^(k)(r) / T^k`` (eqs. 8-9
for k = 1, 2). Everything here is for one path and computed in float64: the polynomial with
NumPy, the torques with ``jaxarm.model.dynamics`` (jit-compiled, under ``jax.enable_x64``).

``min_duration``:

- *kinematic limits*: the peak of ``|theta_j^(k)|`` over r in [0, 1] is found exactly, at the
  ends or at a real root of the next derivative (``numpy.polynomial`` roots polished by Newton
  steps, and a grid of r as a safeguard); then ``T >= (peak / limit)^(1/k)`` in closed form.
- *torque limits*: torques are ``A(r) / T^2 + G(r)``, with ``A`` the torques of the motion at
  T = 1 without gravity and ``G`` the static gravity load at the posture theta(r) (the
  velocity and acceleration terms both scale with 1 / T^2). With ``s = 1 / T^2`` every r and
  joint allows ``s <= (limit - sign(A) G) / |A|``; the smallest such bound over r is searched
  on a grid of 4,001 points of r refined three times around the 8 best, and T is widened by
  ``1e-9`` relative against rounding (``tests/test_trajectory.py`` checks the peaks at the
  returned T on a dense grid). A torque limit at or
  below the static load somewhere on the path can never be met: a ValueError names it.
"""

from __future__ import annotations

import json
import math
import pathlib
from typing import NamedTuple

import jax
import numpy as np
from numpy.polynomial import polynomial as poly

from jaxarm._validate import finite_scalar, finite_vector, positive_scalar, representable
from jaxarm.io.files import text_writer, write_or_return
from jaxarm.model import dynamics, path
from jaxarm.model.problem import Problem, check_problem

TORQUE_GRID = 4001  # points of r for the torque search
TORQUE_REFINE = (8, 65, 3)  # best points refined, points per local grid, rounds
PEAK_GRID = 1001  # points of r checked beside the roots
SAFETY = 1e-9  # relative widening of the returned duration
# s: the shortest duration. Derivatives divide by T^3 (jerk), so above it every path whose
# coefficients float32 holds has finite float64 derivatives.
MIN_DURATION = 1e-6
MAX_ROWS = 10**7  # rows of ``table`` (and of an export): bounds its float64 columns' memory


class TrajectoryPoint(NamedTuple):
    """Joint states at some times, each of shape (m, n_joints)."""

    position: np.ndarray  # rad
    velocity: np.ndarray  # rad/s
    acceleration: np.ndarray  # rad/s^2
    jerk: np.ndarray  # rad/s^3


class Trajectory:
    """One path of a problem, timed over ``duration`` seconds.

    Args:
      problem: the problem (its arm's ``masses`` are needed for ``torques``).
      x: the path's free parameters, shape (n_free,).
      duration: the transfer time T (s), finite and at least ``MIN_DURATION`` (1e-6 s).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> traj = jaxarm.Trajectory(problem, [66.7388, -28.1028, -9.8855], duration=2.0)
      >>> state = traj.at([0.0, 1.0, 2.0])
      >>> state.velocity.shape, round(float(abs(state.velocity[[0, 2]]).max()), 9)
      ((3, 3), 0.0)
    """

    def __init__(self, problem: Problem, x, duration: float):
        self.problem = check_problem(problem)
        self.x = representable("x", finite_vector("x", x, problem.n_free))
        if np.ndim(duration) == 0 and not isinstance(duration, (bool, str)) and duration == 0:
            # what min_duration gives a path that does not move
            raise ValueError("duration must be > 0, got 0.0 (min_duration's answer for a path "
                             "that does not move: any duration meets its limits)")
        self.duration = positive_scalar("duration", duration)
        if self.duration < MIN_DURATION:
            raise ValueError(f"duration must be at least {MIN_DURATION:g} s, got {duration!r}")
        # coefficients[k]: of the k-th derivative in r, k = 0..5, shape (n_joints, degree + 1 - k)
        base = path.polynomial_coefficients(np.asarray(problem.start), np.asarray(problem.goal),
                                            self.x, problem.degree)
        self.coefficients = [base]
        for _ in range(5):
            self.coefficients.append(poly.polyder(self.coefficients[-1], axis=-1))

    def __repr__(self) -> str:
        return (f"Trajectory({self.problem.name}, x={np.round(self.x, 4).tolist()}, "
                f"duration={self.duration:g} s)")

    def _times(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if t.ndim != 1:
            raise ValueError(f"t must be a 1-D array of times (s), got shape {t.shape}")
        bad = ~(np.isfinite(t) & (t >= 0.0) & (t <= self.duration))
        if bad.any():
            raise ValueError(f"t must lie in [0, duration = {self.duration:g}] s, got "
                             f"{float(t[np.argmax(bad)])!r}")
        return t

    def derivative(self, r, order: int) -> np.ndarray:
        """``d^order theta / dr^order`` at normalised times r (shape (m,)); (m, n_joints)."""
        return _polyval(self.coefficients[order], r)

    def at(self, t) -> TrajectoryPoint:
        """Position, velocity, acceleration and jerk at times ``t`` (s), shape (m,).

        Returns:
          ``TrajectoryPoint`` of arrays of shape (m, n_joints).

        Raises:
          ValueError: for times outside [0, duration] or non-finite.
        """
        r = self._times(t) / self.duration
        return TrajectoryPoint(*(self.derivative(r, k) / self.duration ** k for k in range(4)))

    def torques(self, t) -> np.ndarray:
        """Joint torques (N m) at times ``t`` (s), shape (m,) -> (m, n_joints).

        Raises:
          ValueError: if the arm's masses are not set, or for times outside [0, duration].
        """
        state = self.at(t)
        return _torques(self.problem.arm, state.position, state.velocity, state.acceleration)

    def sample_times(self, rate: float) -> np.ndarray:
        """``0, 1/rate, 2/rate, ...`` up to the duration, which is always the last time."""
        rate = positive_scalar("rate", rate)
        steps = np.arange(sample_count(self.duration, rate)) / rate
        steps = steps[steps < self.duration * (1 - 1e-12)]
        return np.append(steps, self.duration)

    def table(self, rate: float = 100.0) -> dict[str, np.ndarray]:
        """Columns sampled at ``rate`` (Hz): ``t``, ``q1..``, ``dq1..``, ``ddq1..`` and, when
        the arm's masses are known, ``tau1..``; each of shape (m,)."""
        t = self.sample_times(rate)
        state = self.at(t)
        columns = {"t": t}
        blocks = [("q", state.position), ("dq", state.velocity), ("ddq", state.acceleration)]
        if self.problem.arm.masses is not None:
            blocks.append(("tau", _torques(self.problem.arm, *state[:3])))
        for prefix, values in blocks:
            for joint in range(values.shape[1]):
                columns[f"{prefix}{joint + 1}"] = values[:, joint]
        return columns

    def to_csv(self, path_or_file=None, rate: float = 100.0) -> str | pathlib.Path:
        """``table(rate)`` as CSV (a header line, then one row per time): the text, or written
        to ``path_or_file`` (a path, whose suffix ``.gz`` compresses it, or an open text file;
        then that is returned). Units: s, rad, rad/s, rad/s^2, N m."""
        columns = self.table(rate)
        return write_or_return(path_or_file, lambda target: np.savetxt(  # streamed, not a text
            target, np.column_stack(list(columns.values())), delimiter=",",
            header=",".join(columns), comments="", fmt="%.10g"))

    def to_json(self, path_or_file=None, rate: float = 100.0) -> str | pathlib.Path:
        """The trajectory as JSON: problem name, x, duration, rate, units and ``table(rate)``'s
        columns: the text, or written to ``path_or_file`` (then that is returned)."""
        record = {"problem": self.problem.name, "x": self.x.tolist(),
                  "duration": self.duration, "rate": float(rate),
                  "units": {"t": "s", "q": "rad", "dq": "rad/s", "ddq": "rad/s^2", "tau": "N m"},
                  "columns": {name: values.tolist() for name, values in self.table(rate).items()}}
        return write_or_return(path_or_file,
                               text_writer(json.dumps(record, indent=1, allow_nan=False)))

    def peaks(self) -> dict[str, np.ndarray]:
        """Peak ``|velocity|``, ``|acceleration|``, ``|jerk|`` over the motion, each shape
        (n_joints,) (exact extrema, see ``min_duration``)."""
        return {name: peak_derivative(self.coefficients, order) / self.duration ** order
                for order, name in ((1, "velocity"), (2, "acceleration"), (3, "jerk"))}


def sample_count(duration: float, rate: float) -> int:
    """How many times ``Trajectory.sample_times(rate)`` has before the end (up to one more):
    ``floor(duration * rate) + 1``, or a ValueError naming the rate above ``MAX_ROWS``."""
    span = duration * rate * (1 + 1e-12)
    if not span < MAX_ROWS:  # inf too
        raise ValueError(f"rate {rate:g} Hz over {duration:g} s gives {span:.3g} rows; at most "
                         f"{MAX_ROWS:.0e}")
    return math.floor(span) + 1


def _polyval(coefficients: np.ndarray, r) -> np.ndarray:
    """Polynomials (n_joints, n_terms), ascending powers, at r (m,) -> (m, n_joints)."""
    r = np.asarray(r, np.float64)
    value = np.zeros(r.shape + coefficients.shape[:1])
    for term in coefficients.T[::-1]:  # Horner
        value = value * r[:, None] + term
    return value


def peak_derivative(coefficients: list, order: int) -> np.ndarray:
    """``max_r |theta_j^(order)(r)|`` over [0, 1] per joint, exactly: at the ends or at a real
    root of the next derivative in [0, 1] (each root polished by two Newton steps; a grid of
    ``PEAK_GRID`` points of r guards against a root the eigenvalue method misses).

    Args:
      coefficients: ``Trajectory.coefficients``: derivatives 0..5 of every joint.
      order: 1, 2 or 3.

    Returns:
      Array of shape (n_joints,).
    """
    peaks = []
    for joint in range(coefficients[0].shape[0]):
        values, slope, curve = (coefficients[order + k][joint] for k in range(3))
        candidates = np.linspace(0.0, 1.0, PEAK_GRID).tolist()
        if np.any(slope != 0):
            roots = poly.polyroots(np.trim_zeros(slope, "b"))
            real = roots.real[np.abs(roots.imag) <= 1e-7 * (1 + np.abs(roots.real))]
            for _ in range(2):  # Newton on the slope, where it is not flat
                denominator = poly.polyval(real, curve)
                safe = np.abs(denominator) > 0
                real = np.where(safe, real - poly.polyval(real, slope)
                                / np.where(safe, denominator, 1.0), real)
            candidates.extend(np.clip(real, 0.0, 1.0).tolist())
        peaks.append(np.abs(poly.polyval(np.asarray(candidates), values)).max())
    return np.asarray(peaks)


def _torques(arm, position, velocity, acceleration, gravity=None) -> np.ndarray:
    """Torques (N m) of ``arm`` in float64; ``gravity`` overrides the arm's."""
    lengths, masses, arm_gravity = dynamics.rigid_body(arm)
    gravity = arm_gravity if gravity is None else gravity
    with jax.enable_x64(True):
        return np.asarray(dynamics.inverse_dynamics(lengths, masses, position, velocity,
                                                    acceleration, gravity=gravity))


def per_joint_limit(field: str, value, n_joints: int) -> np.ndarray | None:
    """A limit as shape (n_joints,) (a scalar applies to every joint), or None."""
    if value is None:
        return None
    array = (np.full(n_joints, finite_scalar(field, value)) if np.ndim(value) == 0
             else finite_vector(field, value, n_joints))
    bad = np.nonzero(~(array > 0))[0]
    if bad.size:
        raise ValueError(f"{field}[{int(bad[0])}] must be > 0, got {float(array[bad[0]])!r}")
    return array


def min_duration(problem: Problem, x, *, max_velocity=None, max_acceleration=None,
                 max_jerk=None, max_torque=None, allow_colliding: bool = False) -> float:
    """The shortest transfer time T (s) for which the path respects every limit given.

    Args:
      problem: the problem (``max_torque`` needs its arm's masses).
      x: the path's free parameters, shape (n_free,).
      max_velocity: rad/s, a scalar for every joint or one value per joint; each > 0.
      max_acceleration: rad/s^2, the same way.
      max_jerk: rad/s^3, the same way.
      max_torque: N m, the same way.
      allow_colliding: time a path that collides too. By default a path that is not
        collision-free under the problem's check (``jaxarm.violation`` > 0: it hits an
        obstacle, leaves a joint range, or, under the certified check, is not proved free) is
        an error: no duration makes it a motion to run.

    Returns:
      T in seconds (0.0 for a path that does not move and feels no gravity).

    Raises:
      ValueError: when no limit is given, a limit is not a positive finite number (or has the
        wrong length), a torque limit is at or below the static gravity load on the path, the
        limits allow less than ``MIN_DURATION``, or the path collides (unless
        ``allow_colliding``).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> x = [66.7388, -28.1028, -9.8855]
      >>> T = jaxarm.min_duration(problem, x, max_velocity=1.0)
      >>> peak = jaxarm.Trajectory(problem, x, T).peaks()["velocity"].max()
      >>> round(float(peak), 6)
      1.0
    """
    trajectory = Trajectory(problem, x, duration=1.0)
    limits = {name: per_joint_limit(name, value, problem.n_joints) for name, value in (
        ("max_velocity", max_velocity), ("max_acceleration", max_acceleration),
        ("max_jerk", max_jerk), ("max_torque", max_torque))}
    if all(limit is None for limit in limits.values()):
        raise ValueError("min_duration needs at least one of max_velocity, max_acceleration, "
                         "max_jerk, max_torque")
    duration = 0.0
    for order, name in ((1, "max_velocity"), (2, "max_acceleration"), (3, "max_jerk")):
        if limits[name] is not None:
            peak = peak_derivative(trajectory.coefficients, order)
            duration = max(duration, float(np.max((peak / limits[name]) ** (1.0 / order))))
    if limits["max_torque"] is not None:
        check_static_load(problem, limits["max_torque"])
    if not allow_colliding:
        _check_free(problem, trajectory.x)
    if limits["max_torque"] is not None:
        duration = max(duration, _torque_duration(trajectory, limits["max_torque"]))
    if 0 < duration < MIN_DURATION:
        given = ", ".join(f"{name} {value.tolist()}" for name, value in limits.items()
                          if value is not None)
        raise ValueError(f"the limits ({given}) allow the path a duration of {duration:.3g} s, "
                         f"below the shortest a Trajectory takes ({MIN_DURATION:g} s): limits "
                         "this loose do not bind")
    return duration * (1.0 + SAFETY)


def _check_free(problem: Problem, x: np.ndarray) -> None:
    """A ValueError unless path ``x`` is collision-free under the problem's check."""
    from jaxarm.checks.evaluate import violation

    depth = float(violation(problem, x))
    if depth > 0:
        raise ValueError(f"x is not collision-free in {problem.name} ({problem.collision} "
                         f"check, violation {depth:.4g}): no duration makes it a motion to run; "
                         "pass allow_colliding=True to time it anyway")


def check_static_load(problem: Problem, max_torque) -> np.ndarray:
    """``max_torque`` (a scalar or one value per joint, N m) as shape (n_joints,), checked
    against the static gravity load at the start and goal postures, which every path of the
    problem holds: a limit at or below it raises a ValueError naming the joint."""
    limit = per_joint_limit("max_torque", max_torque, problem.n_joints)
    postures = np.asarray([problem.start, problem.goal])
    still = np.zeros_like(postures)
    static = np.abs(_torques(problem.arm, postures, still, still))
    for which, load in zip(("start", "goal"), static):
        joint = int(np.argmax(load - limit))
        if load[joint] >= limit[joint]:
            raise _overload(limit, joint, load[joint], f"the {which} posture")
    return limit


def _overload(limit: np.ndarray, joint: int, load: float, where: str) -> ValueError:
    """The error for a torque limit that the static gravity load alone reaches at ``where``."""
    return ValueError(f"max_torque[{joint}] = {limit[joint]:g} N m is at or below joint "
                      f"{joint + 1}'s static gravity load {load:.4g} N m at {where}: no "
                      "duration can meet it")


def _torque_duration(trajectory: Trajectory, limit: np.ndarray) -> float:
    """Shortest T with ``|A(r) / T^2 + G(r)| <= limit`` for all r (module docstring)."""
    arm = trajectory.problem.arm

    def split(r):  # A (inertial at T = 1, no gravity) and G (static gravity), (m, n_joints)
        q, dq, ddq = (trajectory.derivative(r, k) for k in range(3))
        still = np.zeros_like(q)
        return _torques(arm, q, dq, ddq, gravity=0.0), _torques(arm, q, still, still)

    def bound(r):  # the largest s = 1 / T^2 each r allows, min over joints; (m,)
        inertial, static = split(r)
        heavy = np.abs(static) >= limit
        if heavy.any():
            index, joint = np.argwhere(heavy)[0]
            raise _overload(limit, joint, abs(static[index, joint]), f"r = {r[index]:.4g}")
        with np.errstate(divide="ignore"):
            allowed = (limit - np.sign(inertial) * static) / np.abs(inertial)
        return allowed.min(axis=1)

    grid = np.linspace(0.0, 1.0, TORQUE_GRID)
    values = bound(grid)
    n_best, n_local, rounds = TORQUE_REFINE
    spacing = grid[1] - grid[0]
    centres = grid[np.argsort(values)[:n_best]]
    best = values.min()
    for _ in range(rounds):
        local = np.clip(centres[:, None] + np.linspace(-spacing, spacing, n_local), 0.0, 1.0)
        local_values = bound(local.ravel()).reshape(local.shape)
        best = min(best, local_values.min())
        centres = local[np.arange(n_best), local_values.argmin(axis=1)]
        spacing *= 2.0 / (n_local - 1)
    return 0.0 if np.isinf(best) else float(1.0 / np.sqrt(best))

