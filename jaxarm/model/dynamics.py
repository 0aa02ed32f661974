"""Rigid-body dynamics of a planar serial arm: the joint torques that produce a motion.

Links are uniform rods: link k of length ``l_k`` (m) and mass ``m_k`` (kg) has its centre of
mass mid-link and inertia ``m_k l_k^2 / 12`` about it. Gravity ``g`` (m/s^2) acts along -y.
Joint angles are relative, as in ``jaxarm.model.arm``; joint k's torque acts between link k - 1 (the
base for k = 1) and link k, positive counter-clockwise.

``inverse_dynamics`` is the recursive Newton-Euler algorithm, unrolled over the (few) links so
that everything stays elementwise over any batch of times. ``tests/test_dynamics.py`` checks it
against the Lagrangian ``d/dt dL/dq' - dL/dq`` computed with ``jax.jacfwd``, and against the
static torques at rest.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm.model.arm import Arm

CM_PER_M = 100.0


def rigid_body(arm: Arm) -> tuple[np.ndarray, np.ndarray, float]:
    """``(lengths in m, masses in kg, gravity)`` of an arm whose masses are known.

    Raises:
      ValueError: if ``arm.masses`` is None.
    """
    if arm.masses is None:
        raise ValueError("arm.masses is not set: torques need the link masses (kg), e.g. "
                         "Arm(lengths, masses=[3.0, 3.0, 2.0]) or [arm] masses in a scenario")
    return (np.asarray(arm.lengths) / CM_PER_M, np.asarray(arm.masses), float(arm.gravity))


@functools.partial(jit, static_argnames=("gravity",), storable=True)
def inverse_dynamics(lengths, masses, position, velocity, acceleration, gravity: float = 9.81):
    """Joint torques of a planar serial arm of uniform rods (recursive Newton-Euler).

    Args:
      lengths: link lengths (m), shape (n_joints,).
      masses: link masses (kg), shape (n_joints,).
      position, velocity, acceleration: joint angles (rad) and their time derivatives
        (rad/s, rad/s^2), each of shape (..., n_joints).
      gravity: m/s^2 along -y (static: 0 and 9.81 compile separately).

    Returns:
      Torques (N m), shape (..., n_joints).
    """
    position, velocity, acceleration = (jnp.asarray(a) for a in (position, velocity,
                                                                 acceleration))
    dtype = position.dtype
    lengths = jnp.asarray(lengths, dtype)
    masses = jnp.asarray(masses, dtype)
    n_joints = position.shape[-1]
    # Forward: absolute angle, rate and angular acceleration of each link, and the linear
    # acceleration of each link's centre of mass (the base does not move).
    base_acceleration = (jnp.zeros(position.shape[:-1], dtype),) * 2
    angle = rate = spin = 0.0
    links = []  # (direction, angular acceleration, centre-of-mass acceleration) per link
    for k in range(n_joints):
        angle = angle + position[..., k]
        rate = rate + velocity[..., k]
        spin = spin + acceleration[..., k]
        direction = (jnp.cos(angle), jnp.sin(angle))
        # d2/dt2 of l u(angle) = l (spin J u - rate^2 u), J the 90 degree rotation
        tip = (-spin * direction[1] - rate * rate * direction[0],
               spin * direction[0] - rate * rate * direction[1])
        centre = tuple(b + 0.5 * lengths[k] * t for b, t in zip(base_acceleration, tip))
        links.append((direction, spin, centre))
        base_acceleration = tuple(b + lengths[k] * t for b, t in zip(base_acceleration, tip))
    # Backward: the force f_k and torque tau_k that link k - 1 exerts on link k at joint k.
    outer_force = (0.0, 0.0)
    outer_torque = 0.0
    torques = [None] * n_joints
    for k in reversed(range(n_joints)):
        (ux, uy), spin, (ax, ay) = links[k]
        force = (masses[k] * ax + outer_force[0], masses[k] * (ay + gravity) + outer_force[1])
        half = 0.5 * lengths[k]
        # Moments about the centre of mass: tau_k - tau_{k+1} + (-half u) x f_k
        # - (half u) x f_{k+1} = I spin
        cross = lambda f: ux * f[1] - uy * f[0]  # noqa: E731  (u x f)
        inertia = masses[k] * lengths[k] ** 2 / 12.0
        torque = inertia * spin + outer_torque + half * (cross(force) + cross(outer_force))
        torques[k] = torque
        outer_force, outer_torque = force, torque
    return jnp.stack(jnp.broadcast_arrays(*torques), axis=-1)
