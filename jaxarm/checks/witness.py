"""Where a path collides: the instant of its deepest tested contact, the link and the obstacle.

The certified check finds its instant itself (``certified.CertifiedCheck.witness_r``); the
sampled check's is its deepest sample (``deepest_sample_rows``). The link and the obstacle are
those nearest each other at that instant (``contacts``): every link against every obstacle
slot of the whole world (and, for an arm that checks self-collision, every link that is not
its neighbour), exact distances, so the pair named is one a user can check by hand.
Obstacles are numbered in ``World``'s order: its circles, then its boxes, then its polygons.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._compile.padding import on_padded_rows
from jaxarm.checks import collision as collision_lib
from jaxarm.model import path, self_collision
from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints
from jaxarm.model.path_functions import joint_path
from jaxarm.model.problem import Problem, ProblemArrays, ProblemSpec, as_params

# Postures whose link-obstacle distances are computed at once: memory stays bounded by this
# times the links times the obstacle slots, whatever the batch.
POSTURES_AT_ONCE = 64
# The fewest postures ``clearance_along`` computes in a call (the rest padding): a summary's
# 401 instants and a figure's 201 or 401 run one compiled program.
POSTURES_PADDED = 512


class Witness(NamedTuple):
    """Where paths collide, each field of shape (...,); NaN / -1 where a path does not."""

    r: jax.Array  # the instant of the deepest tested contact
    link: jax.Array  # int32: the link (0-based) nearest an obstacle there
    obstacle: jax.Array  # int32: that obstacle's index in ``World``'s order
    distance: jax.Array  # cm: their distance there (< margin; negative: penetration depth)
    other_link: jax.Array  # int32: for an arm that checks self-collision, the other link
    #   where the contact is between two links (``obstacle`` is then -1); -1 otherwise

    @property
    def found(self):
        """Bool, shape (...,): a contact, with an obstacle or between two links."""
        return (self.obstacle >= 0) | (self.other_link >= 0)


def link_distances(lengths, world, theta):
    """Every link's exact distance to its nearest obstacle at postures, and which slot that is.

    Args:
      lengths: shape (n_joints,).
      world: ``WorldArrays`` (its near tables, if any, are not read: every slot is).
      theta: postures, shape (P, n_joints).

    Returns:
      ``(distance, slot, other)``, each of shape (P, n_joints): cm (+inf and slot -1 in a
      world without obstacles), int32, and for an arm that checks self-collision the link
      nearer than any obstacle (its slot then -1), else -1.
    """
    world = world._replace(near=None)
    valid = jnp.concatenate([world.circle_valid, world.polygon_valid])
    n_joints = theta.shape[-1]
    circles = jnp.asarray(world.circles, theta.dtype)

    def obstacles(stacked):  # (n_joints, n_slots): the links and the obstacles as array axes,
        # compiled once whatever their numbers
        if valid.shape[0] == 0:
            return jnp.full((n_joints, 1), jnp.inf, theta.dtype)
        sx, sy, ex, ey = stacked
        separation = jnp.concatenate([
            world_lib.point_segment_distance(circles[None, :, 0], circles[None, :, 1],
                                             sx[:, None], sy[:, None], ex[:, None], ey[:, None])
            - circles[None, :, 2],
            world_lib.polygon_separation_xy(sx, sy, ex, ey, world, vertex_axis=True).T], axis=1)
        return jnp.where(valid[None], separation, jnp.inf)

    def one(angles):
        links = link_endpoints(lengths, list(angles))
        separation = obstacles(tuple(jnp.stack(coordinate) for coordinate in zip(*links)))
        nearest = separation.min(axis=1)  # inf: only padding slots
        slot = jnp.where(jnp.isinf(nearest), -1, jnp.argmin(separation, axis=1))
        between = _link_separations(links, world)  # (n_joints, n_joints)
        closer = between.min(axis=1) < nearest
        return (jnp.minimum(nearest, between.min(axis=1)),
                jnp.where(closer, -1, slot).astype(jnp.int32),
                jnp.where(closer, jnp.argmin(between, axis=1), -1).astype(jnp.int32))

    return jax.lax.map(one, theta, batch_size=POSTURES_AT_ONCE)


def _link_separations(links: list, world):
    """Exact separations between every two links (``link_endpoints``' tuples) that are not
    neighbours, for an arm that checks self-collision (``jaxarm.model.self_collision``), shape
    (n_joints, n_joints), symmetric, +inf elsewhere (and everywhere for one that does not)."""
    n_joints = len(links)
    between = jnp.full((n_joints, n_joints), jnp.inf, links[0][0].dtype)
    if world.link_walls is None:
        return between
    first, other = np.array(self_collision.pairs(n_joints)).T
    separations = self_collision.stacked_pair_separations(links)
    return between.at[first, other].set(separations).at[other, first].set(separations)


_link_distances = jit(link_distances, label="the distances along the path")


def clearance_along(problem: Problem, x, r):
    """Every link's exact distance to its nearest obstacle along one path (cm; negative: inside
    one) and which obstacle that is (index in ``World``'s order), or, for an arm that checks
    self-collision, which other link where one is nearer.

    Args:
      x: free parameters, shape (n_free,).
      r: instants in [0, 1], shape (n_r,).

    Returns:
      ``(distance, obstacle, other_link)``, NumPy arrays of shape (n_r, n_joints) (-1:
      none).
    """
    arrays = problem.device_arrays()
    # Postures padded to a few counts, at least ``POSTURES_PADDED``: a summary's instants and a
    # figure's share one compiled program.
    found = on_padded_rows(functools.partial(_link_distances, arrays.lengths, arrays.world),
                           joint_path(problem, x, r), POSTURES_PADDED)
    distance, slot, other = (np.asarray(a) for a in found)
    return distance, obstacle_index(problem, slot), other


@functools.partial(jit, static_argnums=0, storable=True)
def _contact_rows(degree: int, arrays: ProblemArrays, rows_and_r):
    """``contacts`` of rows (B, n_free + 1): the free parameters, then r."""
    rows, r = rows_and_r[:, :-1], rows_and_r[:, -1]
    basis = path.basis_values(degree, jnp.nan_to_num(r)[:, None], 0)[:, 0]  # (B, degree - 4)
    theta = jnp.stack(path.joint_angle_list(arrays.start, arrays.goal, rows, basis,
                                            per_path=True), axis=-1)
    distance, slot, other = link_distances(arrays.lengths, arrays.world, theta)
    link = jnp.argmin(distance, axis=1).astype(jnp.int32)
    nearest, slot, other = (jnp.take_along_axis(a, link[:, None], axis=1)[:, 0]
                            for a in (distance, slot, other))
    missing = jnp.isnan(r) | ((slot < 0) & (other < 0))
    return (jnp.where(missing, -1, link), jnp.where(missing, -1, slot),
            jnp.where(missing, jnp.nan, nearest), jnp.where(missing, -1, other))


def contacts(problem: Problem, x, r) -> Witness:
    """The link and obstacle nearest each other on paths ``x`` (..., n_free) at instants ``r``
    (...,; NaN: none, then -1 and NaN), as a ``Witness``. Given on the host, only the paths
    with an instant are computed."""
    x = as_params(problem, x)
    kernel = functools.partial(_contact_rows, problem.degree, problem.device_arrays())
    if isinstance(x, jax.core.Tracer) or isinstance(r, jax.core.Tracer):
        r = jnp.broadcast_to(jnp.asarray(r, x.dtype), x.shape[:-1])
        link, slot, distance, other = on_padded_rows(kernel,
                                                     jnp.concatenate([x, r[..., None]], -1))
        return Witness(r, link, obstacle_index(problem, slot, jnp), distance, other)
    r = np.broadcast_to(np.asarray(r, x.dtype), x.shape[:-1]).reshape(-1)
    rows = x.reshape((r.shape[0], x.shape[-1]))
    link, slot, other = (np.full(r.shape, -1, np.int32) for _ in range(3))
    distance = np.full(r.shape, np.nan, x.dtype)
    hit = np.flatnonzero(~np.isnan(r))
    if hit.size:
        found = on_padded_rows(kernel, np.concatenate([rows[hit], r[hit, None]], axis=1))
        link[hit], slot[hit], distance[hit], other[hit] = (np.asarray(a) for a in found)
    shaped = lambda a: jax.device_put(a.reshape(x.shape[:-1]))  # noqa: E731
    return Witness(shaped(r), shaped(link), shaped(obstacle_index(problem, slot, np)),
                   shaped(distance), shaped(other))


def obstacle_index(problem: Problem, slot, xp=np):
    """Slots of ``problem.arrays.world`` (ints; -1: none) as the obstacles' indices in
    ``World``'s order (circle slots come first, then the boxes' and polygons' slots), in
    NumPy or ``xp=jax.numpy``."""
    n_circle_slots = problem.capacities[0]
    n_circles = len(problem.world.circles)
    return xp.where(slot < 0, -1, xp.where(slot < n_circle_slots, slot,
                                           slot - n_circle_slots + n_circles)).astype(np.int32)


def deepest_sample_fold(lengths, world, x, margin, *, exact: bool) -> path.SampleFold:
    """The sampled check's deepest sample as a fold: ``(depth, index)`` of shape (B,) each, the
    largest ``collision.posture_margin_depth`` over the samples (0: none collides) and the
    first sample where it is reached."""
    def add_sample(carry, sample):
        deepest, index = carry
        depth = collision_lib.posture_margin_depth(lengths, world, sample.derivatives[0],
                                                   margin, exact=exact)
        return jnp.maximum(deepest, depth), jnp.where(depth > deepest, sample.index, index)

    return path.SampleFold(
        init=(jnp.zeros(x.shape[:-1], x.dtype), jnp.zeros(x.shape[:-1], jnp.int32)),
        step=add_sample, finish=lambda carry: carry, max_order=0)


@functools.partial(jit, static_argnums=0, storable=True)
def deepest_sample_rows(spec: ProblemSpec, arrays: ProblemArrays, rows):
    """The r of each path's deepest sample under the sampled check, NaN where none collides."""
    depth, index = path.run_fold(
        deepest_sample_fold(arrays.lengths, arrays.world, rows, arrays.margin,
                            exact=spec.with_margin),
        arrays.start, arrays.goal, rows, spec.degree, spec.n_samples)
    return jnp.where(depth > 0, index.astype(rows.dtype) / (spec.n_samples - 1), jnp.nan)
