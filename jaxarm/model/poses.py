"""Postures from poses: inverse kinematics, for an arm of any number of links.

A pose is where the end-effector is, (x, y) in cm, and which way its last link points, phi
(rad, absolute). A 3-link arm reaches a pose with at most two postures, and the closed form
picks one by the sign of its elbow (joint 2). An arm of more links reaches it with infinitely
many, and the numerical solution picks one by being near a reference posture ``near``:
Levenberg-Marquardt steps on the pose's error from ``near`` itself (least-norm steps: they
move the joints as little as they can), each with a fading pull towards ``near`` projected on
the motions that leave the pose as it is (in JAX, float64). By
default ``near`` is the arm's rest posture for the pose: the first joint pointing at the
target, every other joint bent by ``REST_BEND`` towards the elbow's side.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._validate import finite_scalar, finite_vector
from jaxarm.model.arm import Arm

REST_BEND = 0.5  # rad: the default reference posture's bend at every joint past the first
POSE_TOLERANCE = 1e-9  # cm (and rad times the arm's reach): how close a solution must come
ITERATIONS = 200  # Levenberg-Marquardt steps at most


def inverse_kinematics(arm: Arm, x: float, y: float, phi: float = 0.0, elbow: int = 1,
                       near=None) -> np.ndarray:
    """Joint angles that put the arm's end-effector at (x, y) with its last link along phi.

    Args:
      arm: an arm of 3 or more links.
      x: the end-effector's position along x (cm).
      y: along y (cm).
      phi: the last link's absolute angle (rad).
      elbow: +1 or -1: a 3-link arm's sign of joint 2 (closed form); for more links, the side
        the default reference posture bends to.
      near: optional reference posture, shape (n_joints,): the solution is the one reached
        from it (module docstring), near it. Default: for 3 links, the closed form; for more,
        the rest posture.

    Returns:
      Joint angles (rad), shape (n_joints,), the first and last wrapped to (-pi, pi] (a
      3-link arm's closed form), or as reached from ``near``.

    Raises:
      ValueError: naming the field: fewer than 3 links, a non-finite pose, a ``near`` of
        another length, or a pose out of reach (with the distance it needs).

    Examples:
      >>> arm = jaxarm.Arm(lengths=(20.0, 20.0, 20.0, 20.0, 20.0))
      >>> joints = jaxarm.inverse_kinematics(arm, 50.0, 30.0, 0.5)
      >>> np.round(np.asarray(jaxarm.joint_positions(arm.lengths, joints))[-1], 4).tolist()
      [50.0, 30.0]
    """
    if arm.n_joints < 3:
        raise ValueError(f"a pose (x, y, phi) needs an arm of 3 or more links, got arm.lengths "
                         f"with {arm.n_joints}; give the joints")
    for name, value in (("x", x), ("y", y), ("phi", phi)):
        if isinstance(value, (bool, str, bytes)):  # float() would take True and "1.5"
            raise ValueError(f"pose.{name} must be a number, got {value!r}")
        finite_scalar(f"pose.{name}", value)
    if elbow not in (1, -1):
        raise ValueError(f"pose.elbow must be +1 or -1, got {elbow!r}")
    _check_reach(arm, x, y, phi)
    x, y, phi = float(x), float(y), float(phi)
    if near is None and arm.n_joints == 3:
        return _three_links(arm, x, y, phi, elbow)
    if near is None:
        near = np.full(arm.n_joints, elbow * REST_BEND)
        near[0] = math.atan2(y, x) - elbow * REST_BEND * (arm.n_joints - 1) / 2
    near = finite_vector("pose.near", near, arm.n_joints)
    with jax.enable_x64(True):
        theta, error = (np.asarray(a) for a in _solve(
            jnp.asarray(arm.lengths, jnp.float64), jnp.asarray([x, y, phi], jnp.float64),
            jnp.asarray(near, jnp.float64)))
    if not error <= POSE_TOLERANCE * max(1.0, arm.reach):
        raise ValueError(f"pose (x={x}, y={y}, phi={phi}): no posture found from "
                         f"near={np.round(near, 4).tolist()} (it ends {error:.3g} cm away); "
                         "give another pose.near, or the joints")
    return theta


def _check_reach(arm: Arm, x: float, y: float, phi: float) -> None:
    """A ValueError if the wrist (the last link's base) lies where the other links cannot
    put it: outside the ring of radii [max(0, 2 l_max - L), L], L their total length."""
    *others, last = arm.lengths
    wrist_x = float(x) - last * math.cos(float(phi))
    wrist_y = float(y) - last * math.sin(float(phi))
    distance = math.hypot(wrist_x, wrist_y)
    outer = sum(others)
    inner = max(0.0, 2 * max(others) - outer)
    if not inner <= distance <= outer:
        raise ValueError(
            f"pose (x={x}, y={y}, phi={phi}) is unreachable: the wrist at "
            f"({wrist_x:.4g}, {wrist_y:.4g}) is {distance:.4g} cm from the base, outside "
            f"[{inner:.4g}, {outer:.4g}]")


def _three_links(arm: Arm, x: float, y: float, phi: float, elbow: int) -> np.ndarray:
    """The closed form: the wrist at ``(x, y) - l3 (cos phi, sin phi)``, reached by the
    two-link solution whose elbow angle has the sign ``elbow``."""
    l1, l2, l3 = arm.lengths
    wrist_x, wrist_y = x - l3 * math.cos(phi), y - l3 * math.sin(phi)
    distance = math.hypot(wrist_x, wrist_y)
    cos_elbow = min(1.0, max(-1.0, (distance**2 - l1**2 - l2**2) / (2 * l1 * l2)))
    theta2 = elbow * math.acos(cos_elbow)
    theta1 = math.atan2(wrist_y, wrist_x) - math.atan2(l2 * math.sin(theta2),
                                                       l1 + l2 * math.cos(theta2))
    theta3 = phi - theta1 - theta2
    return np.array([_wrap(theta1), theta2, _wrap(theta3)])


def _pose(lengths, theta):
    """The end-effector's (x, y, reach x phi) of postures: phi scaled to cm, so that one
    step weighs position and orientation alike. Shape (3,)."""
    absolute = jnp.cumsum(theta)
    reach = jnp.sum(lengths)
    return jnp.stack([jnp.dot(lengths, jnp.cos(absolute)), jnp.dot(lengths, jnp.sin(absolute)),
                      reach * absolute[-1]])


@jit
def _solve(lengths, target, near):
    """Levenberg-Marquardt from ``near`` towards the pose ``target`` (x, y, phi), each step's
    pull towards ``near`` projected on the Jacobian's null space. Returns ``(theta,
    error)``: the posture and its distance from the pose (cm; phi's error times the reach)."""
    reach = jnp.sum(lengths)
    goal = jnp.stack([target[0], target[1], reach * target[2]])

    def residual(theta):
        error = goal - _pose(lengths, theta)
        # phi's error wrapped to (-pi, pi]: any turn of the last link is the same pose
        return error.at[2].set(reach * jnp.arctan2(jnp.sin(error[2] / reach),
                                                   jnp.cos(error[2] / reach)))

    def step(state):  # the pull fades, and a rejected step damps the next one more
        theta, damping, pull, count = state
        error = residual(theta)
        jacobian = jax.jacfwd(_pose, argnums=1)(lengths, theta)
        pseudo = jacobian.T @ jnp.linalg.inv(jacobian @ jacobian.T + damping * jnp.eye(3))
        null = jnp.eye(theta.shape[0]) - pseudo @ jacobian
        proposal = theta + pseudo @ error + pull * null @ (near - theta)
        better = jnp.linalg.norm(residual(proposal)) < jnp.linalg.norm(error)
        return (jnp.where(better, proposal, theta),
                jnp.where(better, damping * 0.3, damping * 10.0),
                jnp.where(better, pull * 0.9, pull * 0.1), count + 1)

    def going(state):
        theta, damping, _, count = state
        return ((count < ITERATIONS) & (damping < 1e12)
                & (jnp.linalg.norm(residual(theta)) > 1e-3 * POSE_TOLERANCE * reach))

    start = (near, jnp.asarray(1e-3, near.dtype) * reach**2, jnp.asarray(0.1, near.dtype), 0)
    theta = jax.lax.while_loop(going, step, start)[0]
    return theta, jnp.linalg.norm(residual(theta))


def _wrap(angle: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    wrapped = math.remainder(angle, 2 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped
