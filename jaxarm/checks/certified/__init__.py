"""The certified continuous collision check: a proof for every r in [0, 1], or a witness.

Three stages, all batched over paths (the user guide's model page, "The certified check in
detail", says how each bound is derived):

0. ``samples``: the nearest obstacle at every sample; a link inside an obstacle there is a
   witness, and the path collides.
1. ``windows``: the window around each sample is proved free by cheap bounds on how far the
   links can move over it (``bounds.drift_shortfalls``), or recorded as failing.
2. ``bisection``: the failing windows are split into pieces, each proved free by tighter
   bounds (``bounds``, ``hull``), found colliding at its centre, left undecided within
   ``certify_tol``, or split again, until a path is decided or its budget runs out.

Results per path depend only on that path (its pieces are visited in the same order whatever
else is in the batch, in chunks or lanes of any count, ``CheckSizes``), so they are
bit-identical for any batch size.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxarm.checks.certified.bisection import Work, bisect
from jaxarm.checks.certified.bits import rows_first
from jaxarm.checks.certified.samples import (
    Motion,
    derivative_tables,
    nearest_fold,
    sample_clearances,
)
from jaxarm.checks.certified.windows import dense_window_pass, screened_window_pass
from jaxarm.model import path
from jaxarm.model.problem import ProblemArrays, ProblemSpec

# The most paths to bisect that still get the narrow loop by default (``CheckSizes``): on CPU
# a wide loop pays for its idle lanes, so it waits for more work (``benchmarks/RESULTS.md``,
# *Decisions and negative results*, "The wide bisection loop on CPU too").
FEW_PATHS, FEW_PATHS_CPU = 2048, 4096  # on an accelerator, on CPU


class CheckSizes(NamedTuple):
    """How ``check`` cuts its work into chunks and lanes: static (hashable), and no size
    changes a verdict, only how fast it comes.

    The bisection loop runs until its slowest path is decided, so few lanes suit few paths: it
    has ``few_lanes`` lanes when at most ``few_paths`` paths need bisecting, ``lanes``
    otherwise. Both loops are compiled, except for a batch of at most ``few_paths`` paths,
    which can only need the narrow one.
    """

    window_chunk: int = 1024  # paths per scan of the dense window pass (circles alone)
    swing_chunk: int = 512  # paths per call of the screened window pass's swing test ...
    pair_chunk: int = 4096  # ... and windows per call of its drift test (with polygons)
    lanes: int = 1024  # paths bisected at once (the wide loop) ...
    few_lanes: int = 64  # ... or this many (the narrow loop) when at most few_paths need it
    few_paths: int | None = None  # None: FEW_PATHS_CPU on CPU, else FEW_PATHS (-1: no narrow)

    def narrow_limit(self) -> int:
        """The most paths to bisect that still get the narrow loop: ``few_paths``, or by
        the default backend."""
        if self.few_paths is not None:
            return self.few_paths
        return FEW_PATHS_CPU if jax.default_backend() == "cpu" else FEW_PATHS


class CertifiedCheck(NamedTuple):
    """The certified verdict on a batch of paths, each field of shape (...,)."""

    violation: jax.Array  # >= 0, zero iff free (the guide's model page, "Violation")
    free: jax.Array  # bool: proved collision-free (clearance >= margin) for every r in [0, 1]
    colliding: jax.Array  # bool: a time where a link is closer than the margin was found
    clearance: jax.Array  # cm: see ``Certificate``
    exhausted: jax.Array  # bool: the budget ran out before a verdict
    pieces: jax.Array  # int32: pieces of windows the bisection tested (0: none needed)
    witness_r: jax.Array  # the instant of the deepest tested contact where colliding, else NaN
    #   (the deepest sample, or the centre of the piece the bisection found closer than the
    #   margin: the only tested time that was)


def search_spare(lengths):
    """cm, shape (): what a search's proofs keep beyond the margin (``check``'s ``spare``):
    2**-20 times the arm's reach, 8 to 16 float32 spacings there.

    A search's check and ``certify`` are separately compiled programs whose float32 rounding
    differs, and a swarm drives its best paths to the edge of what its check proves: without a
    spare, ``certify`` found some of a search's best paths undecided
    (``benchmarks/RESULTS.md``, *Decisions and negative results*, "A search's proofs keep a
    spare").
    """
    return 2.0**-20 * jnp.sum(lengths)


def screens_windows(spec: ProblemSpec) -> bool:
    """Whether ``check`` screens the windows (a world with polygon slots:
    ``windows.screened_window_pass``) rather than drift-testing every one (circles alone:
    ``windows.dense_window_pass``); static, from the spec's capacities."""
    _, polygon_slots, _ = spec.capacities
    return polygon_slots > 0


def check(spec: ProblemSpec, arrays: ProblemArrays, x, prove=None, free_only=None,
          spare=0.0, sizes: CheckSizes = CheckSizes()) -> CertifiedCheck:
    """The certified check of paths (module docstring).

    Args:
      spec: the problem's static part (degree, n_samples, certify_budget and capacities are
        read).
      arrays: the problem's data (certify_tol and margin, cm, may be traced).
      x: free parameters, shape (B, n_free).
      prove: optional, shape (B,), bool: the paths to prove. The others get stage 0 only:
        colliding if a sample finds a witness, else neither free nor colliding, with violation
        inf (a search skips the paths that could not change it: ``evaluate.ProofRequest``).
      free_only: optional, shape (B,), bool: paths whose bisection stops at the first piece
        that is not free (a witness or undecided): only whether they are free matters, and
        their violation is what was found by then.
      spare: cm (may be traced), below ``certify_tol``: a window or piece is proved free only
        when its bound keeps the margin plus ``spare``, and one within the tolerance of that
        is undecided (``search_spare``: what a search asks for).
      sizes: chunks and lanes (static; the verdicts are the same for any).

    Returns:
      ``CertifiedCheck`` of arrays of shape (B,).
    """
    degree, n_samples, budget = spec.degree, spec.n_samples, spec.certify_budget
    lengths, world, start, goal = arrays.lengths, arrays.world, arrays.start, arrays.goal
    motion = Motion(lengths, world, start, goal, x)
    dtype = x.dtype
    step = 1.0 / (n_samples - 1)
    tol = jnp.asarray(arrays.certify_tol, dtype)
    margin = jnp.asarray(arrays.margin, dtype)
    proof_margin = margin + jnp.asarray(spare, dtype)  # what the proofs keep
    circles_only = not screens_windows(spec)  # which window pass (module docstring)
    if circles_only:
        nearest, closest = path.run_fold(nearest_fold(lengths, world, x), start, goal, x,
                                         degree, n_samples)
    else:
        clearances = sample_clearances(lengths, world, start, goal, x, degree, n_samples)
        nearest = clearances.min(axis=0)
        closest = jnp.argmin(clearances, axis=0).astype(jnp.int32)
    sample_witness = ~(nearest >= 0)
    unproved = ~sample_witness & (False if prove is None else ~prove)
    open_ = ~sample_witness & ~unproved
    if circles_only:
        windows = dense_window_pass(motion, *rows_first(open_), degree, n_samples,
                                    proof_margin, sizes.window_chunk)
    else:
        windows = screened_window_pass(motion, clearances, open_, degree, n_samples,
                                       proof_margin, sizes.swing_chunk, sizes.pair_chunk)
    needs_work = open_ & (windows.failing != 0).any(axis=1)

    work_rows, n_work = rows_first(needs_work)
    stop_early = jnp.zeros(x.shape[:1], bool) if free_only is None else free_only
    bisect_lanes = functools.partial(
        bisect, motion, Work(windows.failing, closest, stop_early, work_rows, n_work),
        jnp.asarray(derivative_tables(degree, n_samples), dtype), step, tol, margin,
        proof_margin, budget)
    few, many = min(sizes.few_lanes, x.shape[0]), min(sizes.lanes, x.shape[0])
    few_paths = sizes.narrow_limit()
    if few == many or x.shape[0] <= few_paths:  # never more than few_paths to bisect
        out = bisect_lanes(few)
    else:  # a wide loop runs as long as its slowest path: for a few paths, a narrow one
        out = jax.lax.cond(n_work <= few_paths, lambda: bisect_lanes(few),
                           lambda: bisect_lanes(many))

    exhausted = needs_work & out.exhausted
    decided = needs_work & ~exhausted
    colliding = sample_witness | (decided & out.witness)
    free = open_ & ~(needs_work & (out.witness | out.undecided | out.exhausted))
    open_pieces = out.violation + jnp.where(exhausted, tol * step, 0.0)
    violation = jnp.where(sample_witness, margin - nearest,
                          jnp.where(unproved, jnp.inf, jnp.where(needs_work, open_pieces, 0.0)))
    proved = jnp.minimum(-windows.worst_passed, jnp.where(needs_work, out.proved, jnp.inf))
    seen = jnp.where(decided, jnp.minimum(nearest, out.nearest), nearest)
    clearance = jnp.where(free, proof_margin + proved, seen)
    witness_r = jnp.where(sample_witness, closest.astype(dtype) * step,
                          jnp.where(decided & out.witness, out.witness_r, jnp.nan))
    return CertifiedCheck(violation=violation, free=free, colliding=colliding,
                          clearance=clearance, exhausted=exhausted,
                          pieces=jnp.where(needs_work, out.tested, 0), witness_r=witness_r)
