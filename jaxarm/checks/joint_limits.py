"""Joint limits: each joint's angle must stay in a range ``[low, high]`` for every r in [0, 1].

A path that leaves a range counts as colliding (fitness 0), and its *excess* (rad) is added to
the violation: ``sum_j max_r max(theta_j(r) - high_j, low_j - theta_j(r), 0)``.

- Sampled mode (the paper's kind of check) takes the max over the n samples of r.
- Certified mode bounds every r. On each of the ``n_samples - 1`` intervals between samples,
  cut into ``PIECES_PER_INTERVAL`` pieces, a joint angle is a polynomial whose Bernstein
  coefficients on the piece bound it from both sides (the convex-hull property), and whose first
  and last coefficients are its values at the piece's ends. So a path whose coefficients all lie
  within the limits is *proved* inside; one with an end value outside is a *witness* (it leaves
  the range); otherwise it is undecided and counts as violating, by its coefficients' excess.
  On a piece of width w the coefficients lie within ``w^2 / 8 * max|theta''|`` of the curve
  (``tests/test_joint_limits.py`` checks it on random paths), so a path that stays further
  than that inside its limits is always proved: with 101 samples and 4 pieces per interval,
  ``1e-3 rad`` covers ``|theta''| <= 1280 rad`` (for degree 6, ``|g_6''| <= 0.375``: free
  coefficients up to about 3,000).

The Bernstein coefficients of the basis ``[h, g_6, ..., g_d]`` (``jaxarm.model.path``) on each piece
are a float64 table; a path's coefficients are the same linear combination as its angles, so
they stay as well conditioned as the angles themselves.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.model import path

PIECES_PER_INTERVAL = 4


def _excess(theta, low, high):
    """How far angles lie outside ``[low, high]`` (rad), 0 inside; NaN counts as infinite."""
    excess = jnp.maximum(jnp.maximum(theta - high, low - theta), 0.0)
    return jnp.where(jnp.isnan(excess), jnp.inf, excess)


def sampled_fold(limits, x) -> path.SampleFold:
    """Excess at the samples of r, summed over joints: a fold of shape (...,) results.

    Args:
      limits: shape (n_joints, 2), rad.
      x: free parameters, shape (..., n_free) (for the batch shape and dtype).
    """
    limits = jnp.asarray(limits, x.dtype)
    n_joints = limits.shape[0]

    def step(worst, sample):
        theta = sample.derivatives[0]
        return tuple(jnp.maximum(w, _excess(theta[j], limits[j, 0], limits[j, 1]))
                     for j, w in enumerate(worst))

    return path.SampleFold(init=(jnp.zeros(x.shape[:-1], x.dtype),) * n_joints, step=step,
                           finish=sum, max_order=0)


def bernstein_tables(degree: int, n_samples: int, pieces_per_interval: int = PIECES_PER_INTERVAL
                     ) -> np.ndarray:
    """Bernstein coefficients of the basis ``[h, g_6, ..., g_d]`` on each piece of [0, 1].

    Returns:
      float64 array of shape (n_pieces, degree + 1, degree - 4), ``n_pieces = (n_samples - 1)
      * pieces_per_interval`` equal pieces in order; entry ``[p, i, f]`` is basis function f's
      i-th Bernstein coefficient on piece p.
    """
    n_pieces = (n_samples - 1) * pieces_per_interval
    power = path.basis_coefficients(degree)  # (degree - 4, degree + 1), ascending powers
    # On [a, a + w], f(a + w s) = sum_m c'_m s^m with c'_m = sum_n c_n C(n, m) a^(n-m) w^m;
    # Bernstein coefficient i = sum_{m <= i} C(i, m) / C(d, m) c'_m.
    n = np.arange(degree + 1)
    choose = np.array([[math.comb(i, m) for m in n] for i in n], dtype=np.float64)
    to_bernstein = choose / choose[degree][None, :]  # [i, m]; zero above the diagonal
    width = 1.0 / n_pieces
    tables = []
    for piece in range(n_pieces):
        a = piece * width
        shift = np.array([[math.comb(k, m) * a ** (k - m) * width ** m if k >= m else 0.0
                           for m in n] for k in n])  # [n, m]
        tables.append(to_bernstein @ (power @ shift).T)  # (degree + 1, degree - 4)
    return np.stack(tables)


class LimitCheck(NamedTuple):
    """Joint limits over every r in [0, 1] (module docstring), each field of shape (...,)."""

    excess: jax.Array  # rad, >= 0: the Bernstein bound's excess, summed over joints; 0 = proved
    witness: jax.Array  # bool: the angle at some piece end is outside its range


def certified_check(limits, start, goal, x, degree: int, n_samples: int) -> LimitCheck:
    """The certified joint-limit check of paths, one ``lax.scan`` over the pieces of r.

    Args:
      limits: shape (n_joints, 2), rad.
      start, goal: joint angles, shape (n_joints,).
      x: free parameters, shape (..., n_free).
      degree, n_samples: static sizes.

    Returns:
      ``LimitCheck`` of arrays of shape (...,).
    """
    limits = jnp.asarray(limits, x.dtype)
    n_joints = limits.shape[0]

    def body(carry, table):  # table: (degree + 1, degree - 4)
        hull, ends = carry
        coefficients = path.joint_angle_list(start, goal, x, table)  # each (..., degree + 1)
        excess = [_excess(c, limits[j, 0], limits[j, 1]) for j, c in enumerate(coefficients)]
        hull = tuple(jnp.maximum(h, e.max(axis=-1)) for h, e in zip(hull, excess))
        ends = functools.reduce(jnp.maximum, [jnp.maximum(e[..., 0], e[..., -1])
                                              for e in excess], ends)
        return (hull, ends), None

    zeros = jnp.zeros(x.shape[:-1], x.dtype)
    tables = jnp.asarray(bernstein_tables(degree, n_samples), x.dtype)
    (hull, ends), _ = jax.lax.scan(body, ((zeros,) * n_joints, zeros), tables)
    return LimitCheck(excess=sum(hull), witness=ends > 0)

