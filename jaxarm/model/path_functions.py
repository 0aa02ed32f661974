"""A problem's paths as numbers: joint angles along r, all polynomial coefficients, and the
joint angle travelling distance (paper eqs. 5, 6-10), each one compiled program per shape.

Every function takes free parameters ``x`` of shape (..., n_free), any leading batch shape.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._compile.padding import on_padded_rows
from jaxarm.model import path
from jaxarm.model.problem import Problem, as_params


@functools.partial(jit, static_argnums=(0, 1), storable=True)
def _travelling_distance(degree: int, n_samples: int, start, goal, rows):
    """``path.simpson_distance`` of rows (B, n_free) -> (B,), compiled."""
    return path.simpson_distance(start, goal, rows, degree, n_samples)


def travelling_distance(problem: Problem, x) -> jax.Array:
    """Joint angle travelling distance summed over joints (paper eq. 5, Simpson); shape (...,).

    A program of its own, without the collision check: the same values as ``evaluate``'s
    ``distance`` (tested bit for bit).
    """
    return on_padded_rows(functools.partial(_travelling_distance, problem.degree,
                                            problem.n_samples, problem.arrays.start,
                                            problem.arrays.goal), as_params(problem, x))


def joint_path(problem: Problem, x, r, order: int = 0) -> jax.Array:
    """Joint angles (or their ``order``-th derivative with respect to r) along a path, computed
    by one compiled program per shape of x and r.

    Args:
      x: free parameters, shape (..., n_free).
      r: normalised times in [0, 1], shape (n_r,), or one time (a number).
      order: derivative order, 0 to 3.

    Returns:
      Array of shape (..., n_r, n_joints), or (..., n_joints) for one time.

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> jaxarm.joint_path(problem, [66.7388, -28.1028, -9.8855], 0.0).shape
      (3,)
    """
    x = as_params(problem, x)
    if isinstance(order, bool) or order not in range(4):
        raise ValueError(f"order must be 0, 1, 2 or 3, got {order!r}")
    one_time = np.ndim(r) == 0
    if isinstance(r, jax.Array):
        r = jnp.atleast_1d(r)
    else:
        given, r = r, np.atleast_1d(np.asarray(r, dtype=np.float64))
        if r.ndim != 1 or not np.all((r >= 0.0) & (r <= 1.0)):
            raise ValueError(f"r must be normalised times in [0, 1], one or a 1-D array, "
                             f"got {given!r}")
    basis = path.basis_values(problem.degree, r, order)
    angles = _joint_angles(problem.arrays.start, problem.arrays.goal, x, basis, order=order)
    return angles[..., 0, :] if one_time else angles


# One program per shape: run op by op, a call with a new shape compiled several small programs,
# which took longer together than the one program compiled whole.
_joint_angles = jit(path.joint_angle_array, static_argnames="order")


def coefficients(problem: Problem, x) -> jax.Array:
    """All polynomial coefficients ``a_0 .. a_d`` per joint (paper eq. 10 for degree 6).

    Returns:
      Array of shape (..., n_joints, degree + 1), ascending powers.
    """
    x = as_params(problem, x)
    return path.polynomial_coefficients(problem.arrays.start, problem.arrays.goal, x,
                                        problem.degree)

