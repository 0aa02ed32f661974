"""Stage 0 of the certified check: the paths at their samples.

The nearest obstacle at every sample of r (each link's clearance bound, exact where it is
negative). A sample where a link penetrates an obstacle is a *witness*: the path collides,
and the later stages do nothing more for it. Also what every stage reads: the paths and their
problem (``Motion``), and the basis' Taylor coefficients at the samples
(``derivative_tables``), with which a stage expands a path about any sample.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.checks import collision as collision_lib
from jaxarm.model import path
from jaxarm.model import world as world_lib


class Motion(NamedTuple):
    """Paths and the problem data they move in: what every stage of the check reads."""

    lengths: jax.Array  # shape=(n_joints,), cm
    world: world_lib.WorldArrays
    start: jax.Array  # shape=(n_joints,), rad
    goal: jax.Array  # shape=(n_joints,), rad
    x: jax.Array  # shape=(B, n_free), the paths' free parameters


def derivative_tables(degree: int, n_samples: int) -> np.ndarray:
    """Every basis function's derivatives of every order at the samples, divided by the
    order's factorial (Taylor coefficients); float64, shape (n_samples, degree + 1, degree - 4)."""
    r = np.linspace(0.0, 1.0, n_samples)
    return np.stack([path.basis_values(degree, r, order) / math.factorial(order)
                     for order in range(degree + 1)], axis=1)


def nearest_fold(lengths, world, x) -> path.SampleFold:
    """Stage 0 as a fold (in a world of circles alone): the smallest clearance bound of any
    link at any sample (cm; < 0: a penetration, exact) and the first sample where it was
    found, each of shape (B,).

    One value per sample: the window pass's shortfall and this distance share every link's
    distances, and XLA's CPU backend then materialises each link-obstacle distance on its own
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "The window pass computes
    the shortfall alone"), so the window pass runs apart, and only on the paths this one
    finds no witness on.
    """
    def add_sample(carry, sample):
        nearest, closest = carry
        here = functools.reduce(jnp.minimum, collision_lib.posture_clearance_bound(
            lengths, world, sample.derivatives[0], exact=False))
        nearer = jnp.minimum(nearest, here)  # ``here`` read once, for the same reason
        return nearer, jnp.where(nearer < nearest, sample.index, closest)

    return path.SampleFold(
        init=(jnp.full(x.shape[:-1], jnp.inf, x.dtype), jnp.zeros(x.shape[:-1], jnp.int32)),
        step=add_sample, finish=lambda carry: carry, max_order=0)


def sample_clearances(lengths, world, start, goal, x, degree, n_samples):
    """Stage 0 (in a world with polygons, whose window screen reads every sample's value): the
    smallest clearance bound of any link at each sample (cm; < 0: a penetration, exact), shape
    (n_samples, B)."""
    return path.sample_values(
        lambda sample: functools.reduce(jnp.minimum, collision_lib.posture_clearance_bound(
            lengths, world, sample.derivatives[0], exact=False)),
        start, goal, x, degree, n_samples)
