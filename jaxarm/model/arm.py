"""Planar serial arms: link lengths and forward kinematics (paper eqs. 1-4).

The base sits at the origin. Joint angles are relative: link k points along the absolute
angle ``phi_k = theta_1 + ... + theta_k``, and joint k's position is the previous one plus
``l_k (cos phi_k, sin phi_k)``. Link k is the straight segment between positions k-1 and k.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._validate import MAX_CM, finite_scalar, finite_vector, representable


@dataclasses.dataclass(frozen=True)
class Arm:
    """A planar serial arm.

    Args:
      lengths: link lengths (cm), base first; any number of links, each > 0 and at most
        ``MAX_CM`` (1e5 cm: float32 geometry, see ``jaxarm._validate``).
      masses: link masses (kg), one per link, each finite and >= 0, or None when unknown
        (kinematics only; ``jaxarm.model.dynamics`` needs them). Links are uniform rods.
      gravity: gravitational acceleration along -y (m/s^2), finite and >= 0; 0 for an arm
        moving in a horizontal plane.
      self_collision: whether links that are not neighbours must keep apart (by the
        problem's margin), as a real planar arm's links, which share one plane, must. Off by
        default: the paper's scenes and numbers assume it off.

    Examples:
      >>> Arm(lengths=(30.0, 30.0, 20.0)).n_joints
      3
    """

    lengths: tuple[float, ...]
    masses: tuple[float, ...] | None = None
    gravity: float = 9.81
    self_collision: bool = False

    def __post_init__(self):
        lengths = finite_vector("arm.lengths", self.lengths)
        if lengths.size == 0:
            raise ValueError("arm.lengths must name at least one link, got []")
        for index, length in enumerate(lengths):
            if length <= 0:
                raise ValueError(f"arm.lengths[{index}] must be > 0, got {float(length)!r}")
        representable("arm.lengths", lengths, MAX_CM, " cm")
        object.__setattr__(self, "lengths", tuple(float(v) for v in lengths))
        if self.masses is not None:
            masses = finite_vector("arm.masses", self.masses)
            if masses.size != lengths.size:
                raise ValueError(f"arm.masses must have one value per link ({lengths.size}), "
                                 f"got {masses.size}: {list(self.masses)!r}")
            for index, mass in enumerate(masses):
                if mass < 0:
                    raise ValueError(f"arm.masses[{index}] must be >= 0 (kg), "
                                     f"got {float(mass)!r}")
            object.__setattr__(self, "masses", tuple(float(v) for v in masses))
        gravity = finite_scalar("arm.gravity", self.gravity)
        if gravity < 0:
            raise ValueError(f"arm.gravity must be >= 0 (m/s^2, acting along -y), "
                             f"got {gravity!r}")
        object.__setattr__(self, "gravity", gravity)
        if not isinstance(self.self_collision, (bool, np.bool_)):
            raise ValueError(f"arm.self_collision must be true or false, got "
                             f"{self.self_collision!r}")
        object.__setattr__(self, "self_collision", bool(self.self_collision))

    @property
    def n_joints(self) -> int:
        return len(self.lengths)

    @property
    def reach(self) -> float:
        """Largest distance from the base the end-effector can reach (cm)."""
        return float(sum(self.lengths))


def sincos(angle):
    """``(sin(angle), cos(angle))``; in float32 by a fused polynomial.

    XLA's float32 sin and cos do not vectorise on CPU and dominate forward kinematics. In
    float32 this reduces to [-pi/2, pi/2] and evaluates Taylor polynomials of degree 11 and 12
    (truncation error below 1e-7 there), after a Cody-Waite range reduction; the error stays
    within a few float32 ulps of 1 for |angle| up to thousands of radians (tested). Other dtypes
    use jnp.sin and jnp.cos.
    """
    if angle.dtype != jnp.float32:
        return jnp.sin(angle), jnp.cos(angle)
    turns = jnp.round(angle * np.float32(1 / (2 * math.pi)))
    # Cody-Waite: 2 pi = 6.28125 + rest, the first part exact in few bits, so turns * 6.28125
    # has no rounding error and the reduction stays accurate for large angles.
    y = (angle - turns * np.float32(6.28125)) - turns * np.float32(2 * math.pi - 6.28125)
    flip = jnp.abs(y) > np.float32(math.pi / 2)  # sin(pi - y) = sin y, cos(pi - y) = -cos y
    y = jnp.where(flip, jnp.where(y > 0, np.float32(math.pi), np.float32(-math.pi)) - y, y)
    z = y * y
    sine, cosine = np.float32(0.0), np.float32(0.0)
    for power in (11, 9, 7, 5, 3, 1):  # Horner in z for y (1 - z/3! + z^2/5! - ...)
        sine = sine * z + np.float32((-1) ** (power // 2) / math.factorial(power))
    for power in (12, 10, 8, 6, 4, 2, 0):
        cosine = cosine * z + np.float32((-1) ** (power // 2) / math.factorial(power))
    return y * sine, jnp.where(flip, -cosine, cosine)


def link_endpoints(lengths, theta) -> list[tuple]:
    """Every link's end points, one tuple per link, unrolled over the (few) joints.

    Each coordinate is its own array over the batch, so everything downstream stays
    elementwise (a cumulative sum over an axis of length 3 compiles to a slow loop on CPU).

    Args:
      lengths: link lengths, shape (n_joints,).
      theta: relative joint angles (rad), shape (..., n_joints), or a list of n_joints arrays
        of shape (...).

    Returns:
      A list of n_joints tuples ``(start_x, start_y, end_x, end_y)``, each of shape (...).
    """
    if not isinstance(theta, (list, tuple)):
        theta = jnp.asarray(theta)
        theta = [theta[..., k] for k in range(theta.shape[-1])]
    lengths = jnp.asarray(lengths, dtype=theta[0].dtype)
    x = y = jnp.zeros(theta[0].shape, theta[0].dtype)
    absolute = 0.0
    links = []
    for k, angle in enumerate(theta):
        absolute = absolute + angle
        sine, cosine = sincos(absolute)
        next_x = x + lengths[k] * cosine
        next_y = y + lengths[k] * sine
        links.append((x, y, next_x, next_y))
        x, y = next_x, next_y
    return links


def joint_positions(lengths, theta) -> jnp.ndarray:
    """Joint positions, base first, for any leading batch shape (paper eqs. 1-3).

    Args:
      lengths: link lengths, shape (n_joints,) (a list, tuple or array).
      theta: relative joint angles (rad), shape (..., n_joints) (a list, tuple or array; a
        number for a 1-link arm).

    Returns:
      Positions, shape (..., n_joints + 1, 2); index 0 is the base (0, 0), the last the
      end-effector.

    Raises:
      ValueError: naming the argument, for angles or lengths that are not real numbers or
        whose shapes do not match.

    Examples:
      >>> jaxarm.joint_positions([30, 30, 20], [0.0, 0.0, 0.0])[-1].tolist()
      [80.0, 0.0]
    """
    theta = jnp.asarray(_real("theta", theta))
    if not jnp.issubdtype(theta.dtype, jnp.floating):
        theta = theta.astype(jnp.result_type(float))
    lengths = jnp.asarray(_real("lengths", lengths), theta.dtype)
    if lengths.ndim != 1 or lengths.shape[0] == 0:
        raise ValueError(f"lengths must have shape (n_joints,), got shape {lengths.shape}")
    if theta.ndim == 0 and lengths.shape[0] == 1:  # one link: one angle
        theta = theta[None]
    if theta.ndim == 0 or theta.shape[-1] != lengths.shape[0]:
        raise ValueError(f"theta must have shape (..., {lengths.shape[0]}) for "
                         f"{lengths.shape[0]} links, got shape {theta.shape}")
    links = link_endpoints(lengths, theta)
    points = [(links[0][0], links[0][1])] + [(ex, ey) for _, _, ex, ey in links]
    return jnp.stack([jnp.stack(point, axis=-1) for point in points], axis=-2)


def _real(field: str, values):
    """``values`` as an array of real numbers (traced values pass as they are), or a
    ValueError naming ``field``."""
    if isinstance(values, jax.core.Tracer):
        return values
    try:
        array = np.asarray(values)
    except ValueError:  # ragged
        array = None
    if array is None or array.dtype.kind not in "biuf":
        raise ValueError(f"{field} must be real numbers, got {values!r}")
    return array
