"""The paper's sampled collision check (Fig. 8), and the clearance of a posture.

``sampled_fold``: the links are checked against every obstacle at the ``n`` equally spaced
samples of r, a fold along the samples (``path.run_fold``). A thin obstacle can slip between
two samples. With a margin m > 0 a link closer than m to an obstacle counts too (exact
distances then; without a margin the separating-axis gap suffices, see ``world``).

Violation (for constraint handling): ``max(m - separation, 0)`` summed over links and
obstacles at a sample, the largest such sum over the samples (cm: the deepest penetration
found); zero exactly when no sample collides. The deepest penetration rather than its sum over
the samples: the sum rewards paths that swing fast through an obstacle (fewer samples inside),
and under feasibility rules it drew more swarms into such traps (``benchmarks/RESULTS.md``,
*Decisions and negative results*, "Constraint rules compare depth x distance"). The constraint
rules compare it times the path's travelling distance (``constraints.path_measures``).

The certified continuous check (``jaxarm.checks.certified``) reads its samples' clearances
here (``posture_clearance_bound``); its bounds over pieces of a motion are in
``jaxarm.checks.certified.bounds``.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from jaxarm.model import nearby, path, self_collision
from jaxarm.model import world as world_lib
from jaxarm.model.arm import link_endpoints

# Written out, XLA fuses every link's exact polygon distances into one kernel, which runs far
# slower past about this many link-edge pairs; one link at a time (a scan) is slower on small
# worlds, so the scan starts above it (benchmarks/RESULTS.md, Decisions and negative results,
# "The sampled check with a margin on polygon-field").
UNROLLED_LINK_EDGES = 64
# Written out, XLA fuses a posture's whole check into one loop over the batch, and past some
# size LLVM compiles that loop as scalar code: OMPL's chain of 7 links (7 links x 12 wall
# segments) ran over ten times slower than its chain of 6. So a posture's check of more
# link-slot work than this (links x (circle slots + polygon edges)) is cut into groups of
# links of at most this much each, each group compiled apart (``by_groups``)
# (benchmarks/RESULTS.md, Decisions and negative results, "Links in groups compiled apart").
GROUP_WORK = 128


def link_edge_pairs(n_links: int, world) -> int:
    """Links x polygon slots x vertex slots: the exact distances one posture's check takes."""
    return n_links * world.vertices.shape[0] * world.vertices.shape[1]


def link_groups(n_links: int, world) -> list:
    """The links of a posture's check written out (a world without near tables), in groups
    of at most ``GROUP_WORK`` link-slot work (a link at least) on CPU: one group where the
    whole check fits, and on other backends (where a branch reads its condition back to the
    host, and the scalar loop was not seen; untested there). A list of ranges of link
    indices."""
    per_link = nearby.slot_work((world.circles.shape[0], *world.vertices.shape[:2]))
    size = max(1, n_links)
    if per_link * n_links > GROUP_WORK and jax.default_backend() == "cpu":
        size = max(1, GROUP_WORK // per_link)
    return [range(first, min(first + size, n_links)) for first in range(0, n_links, size)]


def by_groups(groups: list, run, carry, lengths, never):
    """``carry = run(group, carry)`` for each group of links in turn (``link_groups``), the
    final carry (a pytree of arrays).

    Past one group, each runs in a branch of its own (a ``lax.cond``), which XLA compiles
    apart, so that each group's operations fuse into a loop of their own (``GROUP_WORK``).
    The branch's condition is that the first link's length is positive, true for every
    valid arm and not known when compiling; the other branch, never taken, gives every
    array of the carry the value ``never``, which proves nothing free (+inf as a depth,
    -inf as a clearance)."""
    if len(groups) == 1:
        return run(groups[0], carry)
    valid = jnp.asarray(lengths)[0] > 0
    for group in groups:
        carry = jax.lax.cond(valid, functools.partial(run, group),
                             lambda carry: jax.tree.map(
                                 lambda a: jnp.full_like(a, never), carry), carry)
    return carry


def posture_margin_depth(lengths, world, theta: list, margin=0.0, *, exact: bool):
    """How deep every link is inside the margin around every obstacle, summed over the links
    and obstacles, at one posture per path (cm).

    Args:
      theta: per-joint angles, each of shape (...,).
      margin: cm, a scalar.
      exact: exact distances (needed for a positive margin), or the separating-axis bound
        for polygons (exact where <= 0: enough for margin 0); see ``world.polygon_slots``.

    Returns:
      Array of shape (...,), >= 0, zero iff every link keeps the margin from every obstacle
      (and, for an arm that checks self-collision, from every link but its neighbours: how
      deep two links cross, or come inside the margin, counts as an obstacle's depth).

    With exact distances and more than ``UNROLLED_LINK_EDGES`` link-edge pairs
    (``link_edge_pairs``), the links are taken one at a time, in a ``lax.scan``. A world
    with near tables (``jaxarm.model.nearby``) tests each link against its listed slots
    alone: the others are farther than the tables' reach, which is at least the margin.
    Otherwise the links are written out, in groups past ``GROUP_WORK`` (``by_groups``).
    """
    total = jnp.zeros_like(theta[0])
    links = link_endpoints(lengths, theta)
    if world.link_walls is not None:  # pairs of links
        for separation in self_collision.pair_separations(links):
            total = total + jnp.maximum(margin - separation, 0.0)
    if world.near is not None:
        for index, link in enumerate(links):
            total = total + nearby.over_blocks(
                world.near, nearby.near_cells(world.near, index, *link),
                lambda block, link: _add_link_margin_depth(
                    jnp.zeros_like(link[0]), link, block, margin, exact=exact), "add", link)
        return total
    if exact and link_edge_pairs(len(links), world) > UNROLLED_LINK_EDGES:
        stacked = tuple(jnp.stack(coordinate) for coordinate in zip(*links))
        total, _ = jax.lax.scan(
            lambda total, link: (_add_link_margin_depth(total, link, world, margin, exact=exact),
                                 None),
            total, stacked)
        return total

    def add_depths(group, total):
        for index in group:
            total = _add_link_margin_depth(total, links[index], world, margin, exact=exact)
        return total
    return by_groups(link_groups(len(links), world), add_depths, total, lengths, jnp.inf)


def _add_link_margin_depth(total, link, world, margin, *, exact: bool):
    """``total`` plus how deep one link (its end points' coordinates) is inside the margin
    around every obstacle slot, added slot by slot."""
    for separation in (world_lib.circle_slots(*link, world)
                       + world_lib.polygon_slots(*link, world, exact=exact)):
        total = total + jnp.maximum(margin - separation, 0.0)
    return total


def posture_clearance_bound(lengths, world, theta: list, *, exact: bool) -> list:
    """Lower bounds on every link's distance to the nearest obstacle at one posture per path.

    Args:
      theta: per-joint angles, each of shape (...,).
      exact: exact distances (``world.separation_parts``, polygon slots as an array axis:
        written out slot by slot, the certified bisection took far longer to compile), or the
        cheaper bound, polygons slot by slot (``world.polygon_slots``: with the slots as an
        axis, the certified check's samples and windows ran far slower on polygon scenes;
        ``benchmarks/RESULTS.md``, *Decisions and negative results*, "Polygons slot by slot in
        the certified check's samples and windows")

    Returns:
      A list of n_joints arrays of shape (...,) (then, for an arm that checks
      self-collision, one per pair of links, ``self_collision.pairs``: their distance);
      negative values are minus a penetration depth; +inf for a world without obstacles.
    """
    links = link_endpoints(lengths, theta)
    bounds = link_clearance_bounds(lengths, world, links, exact=exact)
    if world.link_walls is None:
        return bounds
    return bounds + self_collision.pair_separations(links)


def link_clearance_bounds(lengths, world, links: list, *, exact: bool,
                          by_nearest: bool = False) -> list:
    """``posture_clearance_bound`` of links given by their end points (``link_endpoints``'s
    tuples, each coordinate of shape (...,)) of an arm with link ``lengths``; ``exact`` as
    there.

    In a world with near tables, each link's listed slots, and the tables' reach for every
    other (``jaxarm.model.nearby``): the bound is then exact up to the reach and the reach
    beyond it. Otherwise every slot, the links in groups past ``GROUP_WORK``
    (``by_groups``). ``by_nearest``: in a world with near tables, the cheaper bound (``exact``
    False) differentiated through each link's nearest listed slot alone
    (``nearest_clearance``; the same values, and not differentiable with respect to the
    world's arrays).
    """
    if by_nearest and exact:
        raise ValueError("link_clearance_bounds: by_nearest takes the cheaper bound "
                         "(exact=False), got exact=True")

    def clearance(link, world):
        if exact:
            return smallest_separation(world_lib.separation_parts(*link, world), link[0])
        return _cheaper_clearance(link, world)
    if world.near is not None and by_nearest:
        return [nearest_clearance(world, index, link) for index, link in enumerate(links)]
    if world.near is None:

        def fill(group, bounds):
            return [clearance(links[index], world) if index in group else bound
                    for index, bound in enumerate(bounds)]
        unset = [jnp.full_like(link[0], -jnp.inf) for link in links]
        return by_groups(link_groups(len(links), world), fill, unset, lengths, -jnp.inf)
    return [near_minimum(world, index, link, lambda block, link: clearance(link, block), link)
            for index, link in enumerate(links)]


def near_minimum(world, index, link, value, per_link):
    """The smallest ``value(block, per_link)`` (a pytree of arrays of the link's shape) over
    blocks of the slots listed near link ``index`` (an int, or ints broadcasting with the
    link's coordinates) at end points ``link``, each array at most the tables' reach: a lower
    bound on that value over every obstacle when it is a lower bound on a distance.
    ``per_link``: the links' own data ``value`` reads (``nearby.over_blocks``)."""
    found = nearby.over_blocks(world.near, nearby.near_cells(world.near, index, *link), value,
                               "min", per_link)
    reach = jnp.asarray(world.near.reach, link[0].dtype)
    return jax.tree.map(lambda a: jnp.minimum(a, reach), found)


def nearest_clearance(world, index: int, link):
    """Link ``index``'s clearance bound at end points ``link`` in a world with near tables
    (``link_clearance_bounds``' cheaper value), whose derivative is that of its separation from
    the nearest listed slot alone (zero where the tables' reach bounds it): a clearance is the
    smallest of the slots' separations, so away from ties its derivative is the nearest one's.
    Differentiated through every block instead (the blocks' scan, its branches and their
    kernels, transposed), refine's program took several times as long to trace and compile on
    large worlds (``benchmarks/RESULTS.md``, *Decisions and negative results*, "Refine's
    gradient through the nearest slot alone"). Differentiable with respect to the link's
    coordinates only (the world's arrays are closed over). Shape: the link's coordinates'
    (broadcast together)."""
    @jax.custom_jvp
    def bound(stacked):
        link = tuple(stacked)
        return near_minimum(world, index, link,
                            lambda block, link: _cheaper_clearance(link, block), link)

    @bound.defjvp
    def through_nearest(stacked, tangents):
        link, tangents = tuple(stacked[0]), tuple(tangents[0])
        nearest = nearby.over_blocks(
            world.near, nearby.near_cells(world.near, index, *link),
            lambda block, link: first_smallest(slot_separations(link, block, exact=False)),
            "nearest", link)
        reach = jnp.asarray(world.near.reach, link[0].dtype)
        tangent = jnp.zeros_like(link[0])
        for code, kind in enumerate(nearby.KINDS):
            if getattr(world.near, f"{kind}s"):
                slot = nearby.listed_slot(world.near, nearest, kind)
                _, along = jax.jvp(lambda *link: _cheaper_clearance(link, slot), link,
                                   tangents)
                tangent = jnp.where(nearest.kind == code, along, tangent)
        return (jnp.minimum(nearest.value, reach),
                jnp.where(nearest.value < reach, tangent, jnp.zeros_like(tangent)))
    # The coordinates stacked, one array: a link's end is the next one's start, one traced
    # array, and passed as four arguments, the gradient of two links' bounds together lost one
    # link's part in our runs (benchmarks/RESULTS.md, "Refine's gradient through the nearest
    # slot alone"; not traced to its cause).
    return bound(jnp.stack(jnp.broadcast_arrays(*link)))


def slot_separations(link, world, *, exact: bool) -> list:
    """A link's (end points' coordinates, each of shape (...)) signed separation from every
    slot of ``world``, one array of shape (...) a slot, circles first; ``exact`` as
    ``posture_clearance_bound``'s."""
    if exact:
        parts = world_lib.separation_parts(*link, world)
        return parts.circles + ([] if parts.polygons is None else list(parts.polygons))
    return world_lib.circle_slots(*link, world) + world_lib.polygon_slots(*link, world,
                                                                         exact=False)


def _cheaper_clearance(link, world):
    """The smallest of a link's separations from every slot of ``world`` by the cheaper
    bound (``slot_separations`` with ``exact`` False), of the link's coordinates' shape; +inf
    without slots."""
    return _smallest(slot_separations(link, world, exact=False), jnp.full_like(link[0], jnp.inf))


def first_smallest(values: list):
    """The elementwise smallest of a list of arrays (NaN where one is NaN, as ``jnp.minimum``
    gives), and the position in the list of the first that has it (int32; 0 where every one is
    +inf)."""
    smallest, position = jnp.full_like(values[0], jnp.inf), jnp.zeros(values[0].shape, jnp.int32)
    for index, value in enumerate(values):
        closer = (value < smallest) | jnp.isnan(value)
        smallest = jnp.where(closer, value, smallest)
        position = jnp.where(closer, index, position)
    return smallest, position


def smallest_separation(parts: world_lib.SeparationParts, like):
    """The smallest of links' separations from every obstacle, of ``like``'s shape and type
    (+inf without obstacles)."""
    nearest = (jnp.full_like(like, jnp.inf) if parts.polygons is None
               else parts.polygons.min(axis=0))
    return _smallest(parts.circles, nearest)


def _smallest(values: list, initial):
    """The elementwise minimum of ``initial`` and a list of arrays."""
    return functools.reduce(jnp.minimum, values, initial)


def sampled_fold(lengths, world, x, n_samples: int, margin=0.0, *,
                 exact: bool) -> path.SampleFold:
    """The paper's check as a fold: the deepest penetration (into the margin) over the samples,
    in cm; shape (...,), >= 0, zero iff no sample collides.

    Args:
      lengths, world: the problem's arrays.
      x: free parameters, shape (..., n_free) (for the batch shape and dtype).
      margin: cm, a scalar (may be traced).
      exact: use exact distances (required when the margin may be positive).
    """
    return path.SampleFold(
        init=jnp.zeros(x.shape[:-1], x.dtype),
        step=lambda deepest, sample: jnp.maximum(deepest, posture_margin_depth(
            lengths, world, sample.derivatives[0], margin, exact=exact)),
        finish=lambda deepest: deepest,
        max_order=0,
    )
