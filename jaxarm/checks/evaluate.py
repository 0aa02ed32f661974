"""What a problem's paths score: fitness (paper eq. 17), violation, travelling distance, and the
certified check's verdict, for any batch of paths.

``evaluate`` is the traceable kernel the optimisers call inside their own compiled loops; the
public functions (``fitness``, ``violation``, ``collides``, ``certify``) run one compiled
program per problem spec and padded batch size (``jaxarm._compile.padding``). Every public
function takes free parameters ``x`` of shape (..., n_free), any leading batch shape, in
float32 or float64 (whatever ``x`` is; integers become the default float).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._compile.padding import on_padded_rows
from jaxarm.checks import certified as certified_lib
from jaxarm.checks import collision as collision_lib
from jaxarm.checks import joint_limits as limits_lib
from jaxarm.checks import witness as witness_lib
from jaxarm.model import path
from jaxarm.model.problem import (Problem, ProblemArrays, ProblemSpec, as_params,
                                  check_problem)


class Evaluation(NamedTuple):
    """Everything an optimiser needs about a batch of paths (``jaxarm.evaluate``)."""

    fitness: jax.Array  # shape=(...,), paper eq. 17: 0 on collision, else 1 / distance
    violation: jax.Array  # shape=(...,), >= 0, 0 iff collision-free
    distance: jax.Array  # shape=(...,), joint angle travelling distance (eq. 5)


class ProofRequest(NamedTuple):
    """What a caller needs the certified check to prove of each path, each field of shape
    (...,): a search asks for proofs only of the paths that could change it."""

    objective_above: jax.Array  # prove only the paths whose objective (1 / distance) exceeds
    #   this (-inf: every path); the others' violation is inf unless a sample finds them
    #   colliding
    free_only: jax.Array  # bool: stop at the first piece that is not free (only whether the
    #   path is free matters; its violation is then what was found so far)


def evaluate(spec: ProblemSpec, arrays: ProblemArrays, x,
             request: ProofRequest | None = None) -> Evaluation:
    """Fitness, violation and travelling distance of paths.

    Pure and traceable: ``spec`` must be static under jit, ``arrays`` and ``x`` may be traced.
    All leading axes of ``x`` are flattened into one batch axis first: XLA's CPU loops
    vectorise a long flat axis far better than a short innermost one such as 20 particles.

    Args:
      spec: ``problem.spec``.
      arrays: ``problem.arrays``.
      x: free parameters, shape (..., n_free).
      request: optional ``ProofRequest`` with fields of shape (...,): what the certified check
        must prove (None: every path, fully). With a request, a proof keeps
        ``certified.search_spare`` beyond the margin, so that ``certify`` proves every path a
        search found free. Ignored when sampled.

    Returns:
      ``Evaluation`` of arrays of shape (...,).
    """
    rows = x.reshape((math.prod(x.shape[:-1]), x.shape[-1]))  # -1 fails on empty batches
    if request is not None:
        request = ProofRequest(*(jnp.reshape(field, rows.shape[:1]) for field in request))
    evaluation, _, _ = _check_rows(spec, arrays, rows, request)
    return jax.tree.map(lambda a: a.reshape(x.shape[:-1]), evaluation)


def link_clearances(lengths, world, links: list) -> list:
    """Per link of an arm with link ``lengths``, a lower bound on its signed distance to the
    nearest obstacle (cm; negative inside one; exact for circles), each of the links' batch
    shape: what ``refine``'s barrier descends (``collision.link_clearance_bounds``,
    differentiated through each link's nearest listed slot where the world has near
    tables)."""
    return collision_lib.link_clearance_bounds(lengths, world, links, exact=False,
                                               by_nearest=True)


def compiles_best_at_default_level(spec: ProblemSpec) -> bool:
    """Whether a program holding this spec's check runs faster compiled at XLA's default
    optimisation level than at jaxarm's level 1 on CPU (``jaxarm._compile.jit``), with the same
    results: the certified check screening windows (``certified.screens_windows``; see
    ``benchmarks/RESULTS.md``, "The certified search at XLA's default optimisation level")."""
    return spec.collision == "certified" and certified_lib.screens_windows(spec)


def _check_rows(spec: ProblemSpec, arrays: ProblemArrays, rows,
                request: ProofRequest | None = None):
    """``evaluate`` of paths ``rows``, shape (B, n_free) (``request``: None, or fields of
    shape (B,)), and the checks it ran: (Evaluation, the certified check or None when sampled,
    the joint-limit check or None without limits)."""
    # Separate loops for distance and collision: one scan carrying both was no faster, and
    # slower for the certified check at small batches (XLA splits a bigger loop body into
    # more fusions).
    distance = path.simpson_distance(arrays.start, arrays.goal, rows, spec.degree,
                                     spec.n_samples)
    check = limits = None
    if spec.collision == "sampled":
        violation = path.run_fold(
            collision_lib.sampled_fold(arrays.lengths, arrays.world, rows, spec.n_samples,
                                       arrays.margin, exact=spec.with_margin),
            arrays.start, arrays.goal, rows, spec.degree, spec.n_samples)
    else:
        prove = free_only = None
        spare = 0.0
        if request is not None:  # a search: its proofs keep a spare (``certified.search_spare``)
            prove = ~(1.0 / distance <= request.objective_above)  # NaN: proved
            free_only = request.free_only
            spare = certified_lib.search_spare(arrays.lengths)
        check = certify_rows(spec, arrays, rows, prove, free_only, spare)
        violation = check.violation
    if spec.with_limits:  # joint limits: their excess (rad) adds to the violation
        limits = limit_rows(spec, arrays, rows)
        violation = violation + limits.excess
    # Coefficients so large that float32 overflows in the path (about 1e15 and up) measure NaN:
    # infinitely colliding, as no number can say how far.
    violation = jnp.where(jnp.isnan(violation), jnp.inf, violation)
    fitness = jnp.where(violation == 0, 1.0 / distance, 0.0).astype(rows.dtype)
    return Evaluation(fitness=fitness, violation=violation, distance=distance), check, limits


def certify_rows(spec: ProblemSpec, arrays: ProblemArrays, rows, prove=None,
                 free_only=None, spare=0.0) -> certified_lib.CertifiedCheck:
    """The certified check (``jaxarm.checks.certified``) of paths ``rows``, shape (B, n_free)
    (``prove``, ``free_only``: None, or shape (B,); ``spare``: ``certified.check``)."""
    if rows.shape[0] == 0:  # the bisection's lanes need a path: check one, keep none
        one = certify_rows(spec, arrays, jnp.zeros((1, rows.shape[1]), rows.dtype))
        return jax.tree.map(lambda a: a[:0], one)
    return certified_lib.check(spec, arrays, rows, prove, free_only, spare)


def limit_rows(spec: ProblemSpec, arrays: ProblemArrays, rows) -> limits_lib.LimitCheck:
    """The joint-limit check (``jaxarm.checks.joint_limits``) of paths ``rows``, shape (B, n_free):
    at the samples in sampled mode, for every r in certified mode."""
    if spec.collision == "certified":
        return limits_lib.certified_check(arrays.joint_limits, arrays.start, arrays.goal, rows,
                                          spec.degree, spec.n_samples)
    excess = path.run_fold(limits_lib.sampled_fold(arrays.joint_limits, rows), arrays.start,
                           arrays.goal, rows, spec.degree, spec.n_samples)
    return limits_lib.LimitCheck(excess=excess, witness=excess > 0)


@functools.cache
def folded_evaluate(spec: ProblemSpec):
    """``evaluate`` for one spec, as a function of ``(arrays, x, request)`` (``request`` None or
    a ``ProofRequest`` with fields of shape ``x.shape[:-1]``) whose ``jax.vmap`` over x folds the
    mapped axis into the batch (one long kernel call) instead of adding a short outer axis to
    every array in it. Not reverse-differentiable (``jax.custom_batching``).
    """
    @jax.custom_batching.custom_vmap
    def evaluate_spec(arrays, x, request):
        return evaluate(spec, arrays, x, request)

    @evaluate_spec.def_vmap
    def fold_mapped_axis(axis_size, in_batched, arrays, x, request):
        arrays_batched, x_batched, request_batched = in_batched
        if any(jax.tree.leaves(arrays_batched)):  # several problems: an ordinary vmap
            in_axes = (jax.tree.map(lambda b: 0 if b else None, arrays_batched),
                       0 if x_batched else None,
                       None if request is None
                       else ProofRequest(*(0 if b else None for b in request_batched)))
            result = jax.vmap(functools.partial(evaluate, spec), in_axes=in_axes)(arrays, x,
                                                                                  request)
        else:
            if not x_batched:
                x = jnp.broadcast_to(x, (axis_size,) + x.shape)
            if request is not None:
                request = ProofRequest(*(
                    field if batched else jnp.broadcast_to(field, (axis_size,) + field.shape)
                    for field, batched in zip(request, request_batched)))
            result = evaluate_spec(arrays, x, request)
        return result, Evaluation(True, True, True)

    return evaluate_spec


def vmapped_evaluate(spec: ProblemSpec):
    """``folded_evaluate`` as a search measures: ``(arrays, x, request=None)``, where None asks
    for every path proved in full, with the search's spare (``evaluate``)."""
    evaluate_spec = folded_evaluate(spec)

    def evaluate_with_request(arrays, x, request=None):
        if request is None:  # every path proved, fully
            request = ProofRequest(jnp.full(x.shape[:-1], -jnp.inf, x.dtype),
                                   jnp.zeros(x.shape[:-1], bool))
        return evaluate_spec(arrays, x, ProofRequest(*request))

    return evaluate_with_request


@functools.partial(jit, static_argnums=0, storable=True, label="the collision check")
def _evaluate_and_certify(spec: ProblemSpec, arrays: ProblemArrays, rows):
    """``evaluate`` of paths ``rows``, shape (B, n_free), and for a certified spec their
    ``Certificate`` from the same check (else None): one compiled program per spec and batch
    size serves ``fitness``, ``violation``, ``collides`` and ``certify``: compiled apart, the
    check was compiled twice (``benchmarks/RESULTS.md``, *Decisions and negative results*,
    "One program for the checks")."""
    evaluation, check, limits = _check_rows(spec, arrays, rows)
    if check is None:
        return evaluation, None
    free, colliding = check.free, check.colliding
    if limits is not None:
        colliding = colliding | limits.witness
        free = free & (limits.excess == 0)
    none = jnp.full(rows.shape[:1], -1, jnp.int32)  # link and obstacle: ``certify`` finds them
    clearance = jnp.where(jnp.isnan(check.clearance), -jnp.inf, check.clearance)
    return evaluation, Certificate(free, colliding, clearance,
                                   check.exhausted & ~colliding, check.witness_r, none, none,
                                   none)


def evaluate_paths(problem: Problem, x) -> Evaluation:
    """Fitness, violation and travelling distance of paths, in one pass of the problem's check
    (``jaxarm.evaluate``): what an optimiser needs of each path it asks about.

    Called from the host, the same compiled program as ``fitness`` and ``violation``, so each
    field equals theirs bit for bit, at the cost of one of them. Inside a caller's ``jax.jit``
    or ``jax.vmap`` it is traced into the caller's program, a ``vmap`` folded into one batch of
    paths (``folded_evaluate``, which is not reverse-differentiable).

    Args:
      problem: the problem (its ``collision`` mode decides what colliding means).
      x: free parameters, shape (..., n_free).

    Returns:
      ``Evaluation`` of arrays of shape (...,): ``fitness`` (paper eq. 17), ``violation``
      (>= 0, 0 iff collision-free; +inf where float32 overflows in the path), ``distance``
      (the joint travelling distance, eq. 5).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> evaluation = jaxarm.evaluate(problem, [66.7388, -28.1028, -9.8855])
      >>> float(evaluation.fitness), float(evaluation.violation)  # doctest: +ELLIPSIS
      (0.1946..., 0.0)
    """
    x = as_params(problem, x)
    if isinstance(x, jax.core.Tracer):  # inside the caller's jit or vmap: fold its vmaps
        return folded_evaluate(problem.spec)(problem.arrays, x, None)
    return _evaluated(problem, x)


def _evaluated(problem: Problem, x) -> Evaluation:
    """``evaluate`` of x (..., n_free) in one of a few compiled programs per problem spec (a
    nested ``jax.jit`` inside a caller's trace)."""
    x = as_params(problem, x)  # first: it names a problem that is not one
    return on_padded_rows(functools.partial(_evaluate_and_certify, problem.spec,
                                            problem.device_arrays()), x)[0]



def fitness(problem: Problem, x) -> jax.Array:
    """Paper eq. 17: 0 if any link collides, else 1 / (sum of joint travelling distances).

    Args:
      problem: the problem (its ``collision`` mode decides what colliding means).
      x: free parameters, shape (..., n_free).

    Returns:
      Array of shape (...,).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> float(jaxarm.fitness(problem, [66.7388, -28.1028, -9.8855]))  # doctest: +ELLIPSIS
      0.1946...
    """
    return _evaluated(problem, x).fitness


def violation(problem: Problem, x) -> jax.Array:
    """How much a path collides (cm: the deepest penetration found under the sampled check; under
    the certified check, the user guide's model page, "The certified check in detail").

    Args:
      x: free parameters, shape (..., n_free).

    Returns:
      Array of shape (...,), >= 0 and exactly 0 iff the path is collision-free.
    """
    return _evaluated(problem, x).violation


def collides(problem: Problem, x) -> jax.Array:
    """Whether any link overlaps any obstacle, in the problem's collision mode; shape (...,)."""
    return violation(problem, x) > 0



class Certificate(NamedTuple):
    """The certified check's verdict on paths (``certify``), each field of shape (...,)."""

    free: jax.Array  # bool: proved to keep the margin from every obstacle for all r in [0, 1]
    colliding: jax.Array  # bool: some tested time breaks the margin (never both)
    clearance: jax.Array  # cm: a lower bound on the motion's smallest distance to an obstacle
    #   when free (>= margin); the smallest distance found (< margin; negative: penetration
    #   depth) when colliding; the smallest distance bound seen otherwise
    exhausted: jax.Array  # bool: neither, because the check's budget ran out
    witness_r: jax.Array  # where colliding: the instant of the deepest tested contact (the
    #   deepest sample inside an obstacle, else the tested time the bisection found closer than
    #   the margin); NaN otherwise, and on a path that leaves only a joint limit
    witness_link: jax.Array  # int32: the link (0-based) nearest an obstacle at witness_r; -1
    witness_obstacle: jax.Array  # int32: that obstacle's index in ``World``'s order (its
    #   circles, then its boxes, polygons and segments); -1
    witness_other_link: jax.Array  # int32: for an arm that checks self-collision, the other
    #   link where the contact is between two links (``witness_obstacle`` then -1); -1


def certify(problem: Problem, x) -> Certificate:
    """Prove paths collision-free for every r in [0, 1], or find where they collide.

    Whatever the problem's ``collision`` mode, this runs the certified check: a motion whose
    clearance exceeds ``problem.margin`` by at least ``problem.certify_tol`` everywhere is
    ``free``; one that comes closer than the margin at some tested time is ``colliding``; in
    between (within the tolerance of the margin), or when the budget runs out, neither.
    With ``problem.joint_limits``, ``free`` also needs every joint proved inside its range and
    an angle found outside makes the path ``colliding`` (``clearance`` stays the obstacles').
    A colliding path's witness says where: the instant, and the link and obstacle nearest each
    other there by exact distances over the whole world (``jaxarm.checks.witness``).
    The batch is padded to ``padded_size`` paths (copies of its first path), so a few
    compiled programs serve every batch size; no path's verdict depends on the others in its
    batch.

    Args:
      problem: the problem.
      x: free parameters, shape (..., n_free).

    Returns:
      ``Certificate`` of arrays of shape (...,).

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> certificate = jaxarm.certify(problem, [66.7388, -28.1028, -9.8855])
      >>> bool(certificate.free), bool(certificate.colliding)
      (True, False)
    """
    return _certified_with_witness(problem, x)[0]


def _certified_with_witness(problem: Problem, x) -> tuple[Certificate, witness_lib.Witness]:
    """``certify`` of x, and its witness with the distance there (``collision_witness``)."""
    x = as_params(problem, x)  # first: it names a problem that is not one
    spec = problem.spec._replace(collision="certified")
    certificate = on_padded_rows(functools.partial(_evaluate_and_certify, spec,
                                                   problem.device_arrays()),
                                 x)[1]
    found = witness_lib.contacts(problem, x, certificate.witness_r)
    return certificate._replace(witness_link=found.link, witness_obstacle=found.obstacle,
                                witness_other_link=found.other_link), found


def collision_witness(problem: Problem, x) -> witness_lib.Witness:
    """Where paths collide under the problem's check: the instant of the deepest tested contact
    (sampled check: the sample where the links are deepest inside the obstacles' margins,
    summed over links and obstacles as its violation is; certified: ``certify``'s
    ``witness_r``), and the link and obstacle nearest each other there.

    Args:
      problem: the problem (its ``collision`` mode decides which check).
      x: free parameters, shape (..., n_free).

    Returns:
      ``Witness`` of arrays of shape (...,); NaN / -1 where the check finds no contact (free,
      or undecided under the certified check). A path that leaves only a joint limit has no
      contact either.

    Examples:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> witness = jaxarm.collision_witness(problem, [0.0, 0.0, 0.0])
      >>> int(witness.link), int(witness.obstacle), bool(witness.distance < 0)
      (1, 0, True)
    """
    x = as_params(problem, x)  # first: it names a problem that is not one
    if problem.collision == "certified":
        return _certified_with_witness(problem, x)[1]
    r = on_padded_rows(functools.partial(witness_lib.deepest_sample_rows, problem.spec,
                                         problem.device_arrays()), x)
    return witness_lib.contacts(problem, x, r)


def deepest_contact(problem: Problem, x) -> witness_lib.Witness:
    """Where one path (shape (n_free,)) comes deepest into an obstacle or its margin, by exact
    distances at 4 instants per sample interval (``witness.clearance_along``), or, where
    those find no contact (one thinner than their spacing), ``collision_witness``'s: what a
    summary or a figure shows of a colliding path, without compiling a check when the path's
    contact is wide enough to see. NaN / -1 where neither finds one."""
    check_problem(problem)
    r = np.linspace(0.0, 1.0, 4 * (problem.n_samples - 1) + 1)
    distance, obstacle, other = witness_lib.clearance_along(problem, x, r)
    at, link = np.unravel_index(np.argmin(distance), distance.shape)
    if distance[at, link] < problem.margin:
        return witness_lib.Witness(r=float(r[at]), link=int(link),
                                   obstacle=int(obstacle[at, link]),
                                   distance=float(distance[at, link]),
                                   other_link=int(other[at, link]))
    return collision_witness(problem, x)
