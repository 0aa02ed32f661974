"""Rigid-body torques (``jaxarm.model.dynamics``) against an independent Lagrangian and statics."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxarm
from jaxarm.model import dynamics

LENGTHS = np.array([0.3, 0.3, 0.2])  # m: the paper's arm
MASSES = np.array([3.0, 3.0, 2.0])  # kg: the paper's section 11


def lagrangian_torques(lengths, masses, gravity, q, dq, ddq):
    """``d/dt dL/dq' - dL/dq`` with L = kinetic - potential energy of uniform rods, by
    automatic differentiation (another formulation than Newton-Euler)."""
    def lagrangian(q, dq):
        angle, rate = jnp.cumsum(q), jnp.cumsum(dq)
        base, base_velocity = jnp.zeros(2), jnp.zeros(2)
        energy = 0.0
        for k in range(len(lengths)):
            u = jnp.array([jnp.cos(angle[k]), jnp.sin(angle[k])])
            du = rate[k] * jnp.array([-u[1], u[0]])
            centre = base + lengths[k] / 2 * u
            centre_velocity = base_velocity + lengths[k] / 2 * du
            energy += (0.5 * masses[k] * centre_velocity @ centre_velocity
                       + 0.5 * masses[k] * lengths[k] ** 2 / 12 * rate[k] ** 2
                       - masses[k] * gravity * centre[1])
            base, base_velocity = base + lengths[k] * u, base_velocity + lengths[k] * du
        return energy

    momentum = jax.grad(lagrangian, argnums=1)
    mass_matrix = jax.jacfwd(momentum, argnums=1)(q, dq)
    coupling = jax.jacfwd(momentum, argnums=0)(q, dq)
    return mass_matrix @ ddq + coupling @ dq - jax.grad(lagrangian, argnums=0)(q, dq)


@pytest.mark.parametrize("n_links,gravity", [(3, 9.81), (2, 0.0), (5, 9.81)])
def test_newton_euler_matches_the_lagrangian(n_links, gravity):
    rng = np.random.default_rng(n_links)
    lengths = rng.uniform(0.1, 0.4, n_links)
    masses = rng.uniform(0.5, 4.0, n_links)
    states = rng.normal(size=(6, 3, n_links)) * np.array([1.0, 2.0, 5.0])[None, :, None]
    with jax.enable_x64(True):
        batched = np.asarray(dynamics.inverse_dynamics(
            lengths, masses, states[:, 0], states[:, 1], states[:, 2], gravity=gravity))
        expected = jax.jit(jax.vmap(functools.partial(lagrangian_torques, lengths, masses,
                                                      gravity)))(*states.transpose(1, 0, 2))
        np.testing.assert_allclose(batched, np.asarray(expected), rtol=1e-10, atol=1e-10)


def test_static_torques_are_the_moments_of_the_weights():
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, size=(10, 3))
    with jax.enable_x64(True):
        torque = np.asarray(dynamics.inverse_dynamics(LENGTHS, MASSES, q, 0 * q, 0 * q))
    angle = np.cumsum(q, axis=1)
    joints_x = np.concatenate([np.zeros((10, 1)), np.cumsum(LENGTHS * np.cos(angle), axis=1)],
                              axis=1)
    centres_x = joints_x[:, :-1] + LENGTHS / 2 * np.cos(angle)
    for k in range(3):  # joint k holds every link from k on: sum m g (x_centre - x_joint)
        expected = 9.81 * (MASSES[k:] * (centres_x[:, k:] - joints_x[:, k:k + 1])).sum(axis=1)
        np.testing.assert_allclose(torque[:, k], expected, rtol=1e-12, atol=1e-12)


def test_a_horizontal_arm_at_rest_needs_no_torque():
    q = np.array([[0.3, -1.0, 2.0]])
    torque = dynamics.inverse_dynamics(LENGTHS, MASSES, q, 0 * q, 0 * q, gravity=0.0)
    assert np.all(np.asarray(torque) == 0.0)


def test_arm_masses_and_gravity_are_validated():
    arm = jaxarm.Arm((30.0, 30.0, 20.0), masses=[3, 3, 2], gravity=0)
    assert arm.masses == (3.0, 3.0, 2.0) and arm.gravity == 0.0
    for kwargs, message in [(dict(masses=[3.0, 3.0]), "arm.masses must have one value per link"),
                            (dict(masses=[3.0, -1.0, 2.0]), r"arm.masses\[1\] must be >= 0"),
                            (dict(masses=[3.0, float("nan"), 2.0]), r"arm.masses\[1\]"),
                            (dict(gravity=-9.81), "arm.gravity must be >= 0"),
                            (dict(gravity=float("inf")), "arm.gravity must be finite")]:
        with pytest.raises(ValueError, match=message):
            jaxarm.Arm((30.0, 30.0, 20.0), **kwargs)
    with pytest.raises(ValueError, match="arm.masses is not set"):
        dynamics.rigid_body(jaxarm.Arm((30.0, 30.0, 20.0)))


def test_paper_scenarios_carry_the_papers_masses():
    for name in ("paper-case-1", "paper-case-2", "paper-case-3"):
        arm = jaxarm.load_scenario(name).arm
        assert arm.masses == (3.0, 3.0, 2.0) and arm.gravity == 9.81
