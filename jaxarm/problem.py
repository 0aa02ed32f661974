"""The planning problem and its batched, jit-compiled evaluation (paper eqs. 5, 17).

A ``Problem`` holds the arm, the start and goal postures, the obstacle world and the path
settings. It splits into a static ``ProblemSpec`` (sizes and modes: what a compiled program
depends on) and ``ProblemArrays`` (angles, lengths, obstacles: data), so problems that differ
only in data share one compiled program.

Every public function takes free parameters ``x`` of shape (..., n_free), any leading batch
shape, in float32 or float64 (whatever ``x`` is; integers become the default float).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import certified as certified_lib
from jaxarm import joint_limits as limits_lib
from jaxarm import collision as collision_lib
from jaxarm import path
from jaxarm._validate import finite_scalar, finite_vector, positive_int
from jaxarm import world as world_lib
from jaxarm.arm import Arm, link_endpoints
from jaxarm.world import World, WorldArrays
from jaxarm.choices import COLLISION_MODES, one_of
from jaxarm.programs import jit


@functools.partial(jit, storable=True)
def _posture_depth(lengths, world: WorldArrays, theta):
    """Penetration of every link into every slot at one posture (n_joints,) -> (n_joints, n_slots).

    Compiled: a Problem checks its start and goal on construction, and op by op that took
    about 0.1 s per problem (30 thin-wall problems built by hand: 3.6 s, 0.56 s compiled).
    The lengths (n_joints,) are data and the world is packed at ``_posture_capacities``, so
    that problems of as many joints share the program."""
    return collision_lib.penetration(lengths, world, theta)


@functools.partial(jit, storable=True)
def _posture_separation(lengths, world: WorldArrays, theta):
    """Exact separation (cm) of every link from every slot at one posture, (n_joints, n_slots)."""
    return jnp.stack([world_lib.separation_xy(*link, world)
                      for link in link_endpoints(lengths, list(theta))])


def _posture_capacities(capacities: tuple[int, int, int]) -> tuple[int, int, int]:
    """Slots for the posture checks: at least 4 circles, 4 polygons and 8 vertices, so that
    the shipped scenes of one arm share one program (it checks a single posture)."""
    circles, polygons, vertices = capacities
    return max(circles, 4), max(polygons, 4), max(vertices, 8)


class ProblemSpec(NamedTuple):
    """The static part of a problem: everything a compiled program is specialised on."""

    n_joints: int
    degree: int
    n_samples: int
    collision: str
    capacities: tuple[int, int, int]
    with_margin: bool  # margin > 0: the sampled check needs exact distances
    certify_budget: int
    with_limits: bool = False  # joint limits are checked


class ProblemArrays(NamedTuple):
    """The data part of a problem (a pytree of float64 NumPy arrays)."""

    lengths: np.ndarray  # shape=(n_joints,)
    start: np.ndarray  # shape=(n_joints,), rad
    goal: np.ndarray  # shape=(n_joints,), rad
    world: WorldArrays
    margin: np.ndarray  # shape=(), cm
    certify_tol: np.ndarray  # shape=(), cm
    joint_limits: np.ndarray  # shape=(n_joints, 2), rad; (-inf, inf) rows when there are none


@dataclasses.dataclass(frozen=True)
class Problem:
    """A point-to-point planning problem for a planar arm among obstacles.

    Args:
      arm: the arm.
      start, goal: joint angles (rad), shape (n_joints,).
      world: the obstacles.
      degree: polynomial degree d >= 6 (d - 5 free coefficients per joint).
      n_samples: odd number of points of r in [0, 1] for Simpson's rule and the sampled check.
      collision: ``"certified"`` (default: every r in [0, 1] proved free, see
        ``jaxarm.certified``) or ``"sampled"`` (the paper's check at the n samples only).
      init_low, init_high: range the initial swarm is drawn from, a scalar or shape (n_free,).
      name, description: labels for reports.
      capacities: obstacle slots (circles, polygons, vertices per polygon); default from world.
      margin: clearance (cm) every link must keep from every obstacle; 0 allows grazing.
      certify_tol: the certified check's tolerance (cm): every motion whose clearance exceeds
        the margin by at least this much is certified free.
      certify_budget: pieces the certified check tests per path before it splits no more: a
        piece that needs splitting after that makes the path exhausted (it counts as
        colliding, and ``certify`` reports it). Pieces that need no split are still tested,
        so a path may test a few more. At most ``2**27``.
      joint_limits: one ``(low, high)`` pair per joint (rad), or None. A path that leaves a
        range at any r counts as colliding (see ``jaxarm.joint_limits``: at the samples in
        sampled mode, for every r in certified mode).

    Raises:
      ValueError: naming the field and value, including a start or goal posture that collides.

    Example:
      >>> problem = Problem(arm=Arm((30.0, 30.0, 20.0)), start=[0.0, 0.5, 0.5],
      ...                   goal=[1.0, 0.5, 0.5])
      >>> problem.n_free
      3
    """

    arm: Arm
    start: tuple[float, ...]
    goal: tuple[float, ...]
    world: World = World()
    degree: int = 6
    n_samples: int = 101
    collision: str = "certified"
    init_low: float | tuple[float, ...] = -100.0
    init_high: float | tuple[float, ...] = 100.0
    name: str = "custom"
    description: str = ""
    capacities: tuple[int, int, int] | None = None
    margin: float = 0.0
    certify_tol: float = 0.01
    certify_budget: int = 512
    joint_limits: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self):
        if not isinstance(self.arm, Arm):
            raise ValueError(f"arm must be a jaxarm.Arm, got {self.arm!r}")
        if not isinstance(self.world, World):
            raise ValueError(f"world must be a jaxarm.World, got {self.world!r}")
        set_field = functools.partial(object.__setattr__, self)
        for which in ("start", "goal"):
            set_field(which, _posture(which, getattr(self, which), self.arm))
        degree = positive_int("degree", self.degree, minimum=path.MIN_DEGREE)
        set_field("degree", degree)
        n_samples = positive_int("n_samples", self.n_samples, minimum=3)
        if n_samples % 2 == 0:
            raise ValueError(f"n_samples must be odd for Simpson's rule, got {n_samples}")
        one_of("collision", self.collision, COLLISION_MODES)
        set_field("margin", finite_scalar("margin", self.margin))
        if self.margin < 0:
            raise ValueError(f"margin must be >= 0 (cm), got {self.margin!r}")
        set_field("certify_tol", finite_scalar("certify_tol", self.certify_tol))
        if self.certify_tol <= 0:
            raise ValueError(f"certify_tol must be > 0 (cm), got {self.certify_tol!r}")
        set_field("certify_budget", positive_int("certify_budget", self.certify_budget,
                                                 minimum=1, maximum=certified_lib.MAX_BUDGET))
        low, high = (self._bound(name) for name in ("init_low", "init_high"))
        set_field("init_low", low)
        set_field("init_high", high)
        bad = np.nonzero(~(np.asarray(self.bounds()[0]) < np.asarray(self.bounds()[1])))[0]
        if bad.size:
            raise ValueError(
                f"init_low must be < init_high, got {low!r} and {high!r} (index {int(bad[0])})"
            )
        if self.joint_limits is not None:
            set_field("joint_limits", limits_lib.validate(self.joint_limits, self.n_joints))
            for which in ("start", "goal"):
                for joint, angle in limits_lib.outside(self.joint_limits, getattr(self, which)):
                    low, high = self.joint_limits[joint]
                    raise ValueError(f"{which} joint {joint + 1} is {angle!r} rad, outside "
                                     f"joint_limits[{joint}] = ({low!r}, {high!r})")
        capacities = self.capacities or self.world.capacities()
        self.world.pack(capacities)  # raises if the capacities are too small
        set_field("capacities", tuple(int(c) for c in capacities))
        self._check_postures()

    def _bound(self, name: str):
        value = getattr(self, name)
        if np.ndim(value) == 0:
            return finite_scalar(name, value)
        return tuple(finite_vector(name, value, self.n_free).tolist())

    def _check_postures(self) -> None:
        """Start, then goal: neither may overlap an obstacle or come closer than the margin."""
        dtype = jnp.result_type(float)
        lengths = np.asarray(self.arm.lengths, dtype=dtype)
        capacities = _posture_capacities(self.capacities)
        world, names = self.world.pack(capacities), self.world.slot_names(capacities)
        for which in ("start", "goal"):
            self._check_posture(which, np.asarray(getattr(self, which), dtype=dtype), lengths,
                                world, names)

    def _check_posture(self, which: str, theta, lengths, world, names) -> None:
        depth = np.asarray(_posture_depth(lengths, world, theta))
        if np.any(depth > 0):
            link, slot = np.unravel_index(int(np.argmax(depth > 0)), depth.shape)
            raise ValueError(
                f"{which} posture {list(getattr(self, which))} collides: link {link + 1} "
                f"overlaps {names[slot]} by {depth[link, slot]:.4g} cm"
            )
        if self.margin > 0:
            separation = np.asarray(_posture_separation(lengths, world, theta))
            if np.any(separation < self.margin):
                link, slot = np.unravel_index(int(np.argmin(separation)), separation.shape)
                raise ValueError(
                    f"{which} posture {list(getattr(self, which))} breaks margin "
                    f"{self.margin:g} cm: link {link + 1} is {separation[link, slot]:.4g} cm "
                    f"from {names[slot]}"
                )

    @property
    def n_joints(self) -> int:
        return self.arm.n_joints

    @property
    def n_free(self) -> int:
        """Number of free parameters, ``n_joints * (degree - 5)``."""
        return self.n_joints * path.n_free_per_joint(self.degree)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial-swarm range as two float64 arrays of shape (n_free,)."""
        return tuple(
            np.broadcast_to(np.asarray(v, dtype=np.float64), (self.n_free,)).copy()
            for v in (self.init_low, self.init_high)
        )

    @property
    def spec(self) -> ProblemSpec:
        return ProblemSpec(
            n_joints=self.n_joints,
            degree=self.degree,
            n_samples=self.n_samples,
            collision=self.collision,
            capacities=self.capacities,
            with_margin=self.margin > 0,
            certify_budget=self.certify_budget,
            with_limits=self.joint_limits is not None,
        )

    @functools.cached_property
    def arrays(self) -> ProblemArrays:
        return ProblemArrays(
            lengths=np.asarray(self.arm.lengths),
            start=np.asarray(self.start),
            goal=np.asarray(self.goal),
            world=self.world.pack(self.capacities),
            margin=np.asarray(self.margin),
            certify_tol=np.asarray(self.certify_tol),
            joint_limits=np.asarray(self.joint_limits if self.joint_limits is not None
                                    else [(-np.inf, np.inf)] * self.n_joints),
        )

    def replace(self, **changes) -> "Problem":
        """A copy with some fields changed (and validated again)."""
        return dataclasses.replace(self, **changes)

    def to_toml(self) -> str:
        """This problem as scenario-file text (``jaxarm.save_scenario`` writes it to a file)."""
        from jaxarm.scenarios import to_toml

        return to_toml(self)

    def summary(self) -> str:
        """A few human-readable lines describing the problem."""
        world = self.world
        return "\n".join(
            [
                f"{self.name}: {self.description}".rstrip(": "),
                f"  arm      {self.n_joints} links {list(self.arm.lengths)} cm",
                f"  start    {np.round(self.start, 4).tolist()} rad",
                f"  goal     {np.round(self.goal, 4).tolist()} rad",
                f"  world    {len(world.circles)} circles, {len(world.boxes)} boxes, "
                f"{len(world.polygons)} polygons",
                f"  path     degree {self.degree} ({self.n_free} free coefficients), "
                f"{self.n_samples} samples, {self.collision} collision check"
                + (f", margin {self.margin:g} cm" if self.margin else ""),
                *([f"  limits   {[list(pair) for pair in self.joint_limits]} rad"]
                  if self.joint_limits is not None else []),
                *([f"  masses   {list(self.arm.masses)} kg, gravity {self.arm.gravity:g} m/s^2"]
                  if self.arm.masses is not None else []),
                f"  search   init range [{_describe(self.init_low)}, {_describe(self.init_high)}]",
            ]
        )


MAX_ANGLE = 100.0  # rad; beyond it float32 angles lose the precision the geometry needs


def share_capacities(problems) -> list[Problem]:
    """The problems with one set of obstacle capacities per arm, so that they share compiled
    programs: each gets, slot kind by slot kind, the largest capacities among the problems
    with the same number of joints.

    A search compiles once per capacities (with the arm, degree and check), and compiling is
    most of a short study's time. Padded slots are empty but still computed, so a small scene
    runs slower than at its own capacities (death-trap, 1000 sampled restarts, by hand:
    1.50 s at (0, 1, 4), 2.05 s at (4, 4, 4)); its results are as valid, though not always
    bit for bit the same (another compiled program can round differently in the last bits).
    The quick report uses it for its suite, its rules section and its degree comparison.

    Args:
      problems: ``Problem``s.

    Returns:
      The problems, in order, each with its arm's shared ``capacities``.

    Example:
      >>> from jaxarm import load_scenario
      >>> [p.capacities for p in share_capacities(
      ...     [load_scenario("paper-case-1"), load_scenario("death-trap")])]
      [(4, 1, 4), (4, 1, 4)]
    """
    problems = list(problems)
    for index, problem in enumerate(problems):
        if not isinstance(problem, Problem):
            raise ValueError(f"problems[{index}] must be a jaxarm.Problem, got "
                             f"{type(problem).__name__}")
    largest: dict[int, tuple[int, ...]] = {}
    for problem in problems:
        known = largest.get(problem.n_joints, (0, 0, 0))
        largest[problem.n_joints] = tuple(map(max, known, problem.capacities))
    return [problem if problem.capacities == largest[problem.n_joints]
            else problem.replace(capacities=largest[problem.n_joints]) for problem in problems]


def _posture(which: str, value, arm: Arm) -> tuple[float, ...]:
    """Joint angles for ``arm`` (one per link, finite, within +-MAX_ANGLE), or a ValueError."""
    angles = finite_vector(which, value)
    if angles.size != arm.n_joints:
        raise ValueError(f"{which} has {angles.size} joint angles but arm.lengths "
                         f"{list(arm.lengths)} has {arm.n_joints} links")
    outside = np.nonzero(np.abs(angles) > MAX_ANGLE)[0]
    if outside.size:
        index = int(outside[0])
        raise ValueError(f"{which}[{index}] must be an angle in [-{MAX_ANGLE:g}, {MAX_ANGLE:g}] "
                         f"rad, got {float(angles[index])!r}")
    return tuple(angles.tolist())


def _describe(bound) -> str:
    return f"{bound:g}" if np.ndim(bound) == 0 else str(list(bound))


class Evaluation(NamedTuple):
    """Everything the optimizer needs about a batch of paths."""

    fitness: jax.Array  # shape=(...,), paper eq. 17: 0 on collision, else 1 / distance
    violation: jax.Array  # shape=(...,), >= 0, 0 iff collision-free
    distance: jax.Array  # shape=(...,), joint angle travelling distance (eq. 5)


def evaluate(spec: ProblemSpec, arrays: ProblemArrays, x) -> Evaluation:
    """Fitness, violation and travelling distance of paths.

    Pure and traceable: ``spec`` must be static under jit, ``arrays`` and ``x`` may be traced.
    All leading axes of ``x`` are flattened into one batch axis first: XLA's CPU loops
    vectorise a long flat axis far better than a short innermost one such as 20 particles
    (about 3x at 1000 x 20 paths).

    Args:
      spec: ``problem.spec``.
      arrays: ``problem.arrays``.
      x: free parameters, shape (..., n_free).

    Returns:
      ``Evaluation`` of arrays of shape (...,).
    """
    rows = x.reshape((math.prod(x.shape[:-1]), x.shape[-1]))  # -1 fails on empty batches
    evaluation, _, _ = _check_rows(spec, arrays, rows)
    return jax.tree.map(lambda a: a.reshape(x.shape[:-1]), evaluation)


def _check_rows(spec: ProblemSpec, arrays: ProblemArrays, rows):
    """``evaluate`` of paths ``rows``, shape (B, n_free), and the checks it ran: (Evaluation,
    the certified check or None when sampled, the joint-limit check or None without limits)."""
    # Separate loops for distance and collision: one scan carrying both was no faster, and
    # slower for the certified check at small batches (XLA splits a bigger loop body into
    # more fusions).
    distance = path.travelling_distance(arrays.start, arrays.goal, rows, spec.degree,
                                        spec.n_samples)
    check = limits = None
    if spec.collision == "sampled":
        violation = path.run_fold(
            collision_lib.sampled_fold(arrays.lengths, arrays.world, rows, spec.n_samples,
                                       arrays.margin, exact=spec.with_margin),
            arrays.start, arrays.goal, rows, spec.degree, spec.n_samples)
    else:
        check = certify_rows(spec, arrays, rows)
        violation = check.violation
    if spec.with_limits:  # joint limits: their excess (rad) adds to the violation
        limits = limit_rows(spec, arrays, rows)
        violation = violation + limits.excess
    fitness = jnp.where(violation == 0, 1.0 / distance, 0.0).astype(rows.dtype)  # NaN: 0
    return Evaluation(fitness=fitness, violation=violation, distance=distance), check, limits


def certify_rows(spec: ProblemSpec, arrays: ProblemArrays, rows) -> certified_lib.CertifiedCheck:
    """The certified check (``jaxarm.certified``) of paths ``rows``, shape (B, n_free)."""
    if rows.shape[0] == 0:  # the bisection's lanes need a path: check one, keep none
        one = certify_rows(spec, arrays, jnp.zeros((1, rows.shape[1]), rows.dtype))
        return jax.tree.map(lambda a: a[:0], one)
    return certified_lib.check(arrays.lengths, arrays.world, arrays.start, arrays.goal, rows,
                               spec.degree, spec.n_samples, arrays.certify_tol, arrays.margin,
                               spec.certify_budget)


def limit_rows(spec: ProblemSpec, arrays: ProblemArrays, rows) -> limits_lib.LimitCheck:
    """The joint-limit check (``jaxarm.joint_limits``) of paths ``rows``, shape (B, n_free):
    at the samples in sampled mode, for every r in certified mode."""
    if spec.collision == "certified":
        return limits_lib.certified_check(arrays.joint_limits, arrays.start, arrays.goal, rows,
                                          spec.degree, spec.n_samples)
    excess = path.run_fold(limits_lib.sampled_fold(arrays.joint_limits, rows), arrays.start,
                           arrays.goal, rows, spec.degree, spec.n_samples)
    return limits_lib.LimitCheck(excess=excess, witness=excess > 0)


@functools.cache
def vmapped_evaluate(spec: ProblemSpec):
    """``evaluate`` for one spec, as a function of ``(arrays, x)`` whose ``jax.vmap`` over x
    folds the mapped axis into the batch (one long kernel call) instead of adding a short
    outer axis to every array in it. Not reverse-differentiable (``jax.custom_batching``).
    """
    @jax.custom_batching.custom_vmap
    def evaluate_spec(arrays, x):
        return evaluate(spec, arrays, x)

    @evaluate_spec.def_vmap
    def fold_mapped_axis(axis_size, in_batched, arrays, x):
        arrays_batched, x_batched = in_batched
        if any(jax.tree.leaves(arrays_batched)):  # several problems: an ordinary vmap
            in_axes = (jax.tree.map(lambda b: 0 if b else None, arrays_batched),
                       0 if x_batched else None)
            result = jax.vmap(functools.partial(evaluate, spec), in_axes=in_axes)(arrays, x)
        else:
            if not x_batched:
                x = jnp.broadcast_to(x, (axis_size,) + x.shape)
            result = evaluate_spec(arrays, x)
        return result, Evaluation(True, True, True)

    return evaluate_spec


@functools.partial(jit, static_argnums=0, storable=True)
def _evaluate_and_certify(spec: ProblemSpec, arrays: ProblemArrays, rows):
    """``evaluate`` of paths ``rows``, shape (B, n_free), and for a certified spec their
    ``Certificate`` from the same check (else None): one compiled program per spec and batch
    size serves ``fitness``, ``violation``, ``collides`` and ``certify``. (Compiled apart, the
    check was compiled twice: 5.1 + 5.5 s against 5.6 s for 256 thin-wall paths.)"""
    evaluation, check, limits = _check_rows(spec, arrays, rows)
    if check is None:
        return evaluation, None
    free, colliding = check.free, check.colliding
    if limits is not None:
        colliding = colliding | limits.witness
        free = free & (limits.excess == 0)
    return evaluation, Certificate(free, colliding, check.clearance,
                                   check.exhausted & ~colliding)

SMALL_BATCH = 64  # the smallest padded batch of ``fitness``, ``violation`` and ``certify``
LARGE_BLOCK = 4096  # batches above this are padded to a multiple of it


def padded_size(n_rows: int, smallest: int = SMALL_BATCH) -> int:
    """The batch size that ``n_rows`` paths are padded to before a compiled call: a power of
    two >= ``smallest`` up to ``LARGE_BLOCK``, above it a multiple of ``LARGE_BLOCK``.

    An empty batch is run as ``smallest`` paths (all cut away again). A handful of compiled
    programs then serve every batch size, for under twice the work.
    """
    if n_rows > LARGE_BLOCK:
        return -(-n_rows // LARGE_BLOCK) * LARGE_BLOCK
    return max(smallest, 1 << (max(n_rows, 1) - 1).bit_length())


def on_padded_rows(kernel, x, smallest: int = SMALL_BATCH):
    """``kernel(rows)`` for x's paths as rows (B, n_free), padded with copies of the first path
    to ``padded_size(B, smallest)`` rows; each field of the result, shape (B_padded, *rest),
    cut back to shape x.shape[:-1] + rest.

    Rows are independent (no path's result depends on the others in its batch). A traced x
    (inside the caller's own jit or vmap) is not padded: its program is compiled once anyway.
    """
    if isinstance(x, jax.core.Tracer):
        rows = x.reshape((math.prod(x.shape[:-1]), x.shape[-1]))  # -1 fails on empty batches
        return jax.tree.map(lambda a: a.reshape(x.shape[:-1] + a.shape[1:]), kernel(rows))
    # Padded and cut on the host: done with jax.numpy, each of these steps compiled a small
    # program of its own in every new process (benchmarks/RESULTS.md, "Persistent
    # compilation cache").
    rows = np.asarray(x).reshape((math.prod(x.shape[:-1]), x.shape[-1]))
    n_rows = rows.shape[0]
    first = rows[:1] if n_rows else np.zeros((1, rows.shape[1]), rows.dtype)
    rows = np.concatenate([rows, np.repeat(first, padded_size(n_rows, smallest) - n_rows, 0)])

    def cut(a):
        shape = x.shape[:-1] + a.shape[1:]
        if isinstance(a, jax.core.Tracer):  # a caller's jit holds x as a constant
            return a[:n_rows].reshape(shape)
        return jax.device_put(np.asarray(a)[:n_rows].reshape(shape))

    return jax.tree.map(cut, kernel(rows))


def _evaluated(problem: Problem, x) -> Evaluation:
    """``evaluate`` of x (..., n_free) in one of a few compiled programs per problem spec."""
    return on_padded_rows(functools.partial(_evaluate_and_certify, problem.spec, problem.arrays),
                          _as_params(problem, x))[0]


def _as_params(problem: Problem, x) -> jax.Array:
    if not isinstance(problem, Problem):
        raise ValueError(f"problem must be a jaxarm.Problem, got {type(problem).__name__}")
    if not isinstance(x, jax.core.Tracer):  # checked on the host (no small programs to compile)
        try:
            values = np.asarray(x)
        except ValueError:  # ragged rows
            values = None
        if values is None or values.dtype.kind not in "biuf":
            raise ValueError(f"x must be real numbers, shape (..., {problem.n_free}), got {x!r}")
        x = values.astype(jax.dtypes.canonicalize_dtype(values.dtype))  # as JAX holds it
    if not jnp.issubdtype(x.dtype, jnp.floating):
        x = x.astype(jnp.result_type(float))
    if x.ndim == 0 or x.shape[-1] != problem.n_free:
        raise ValueError(
            f"x must have shape (..., {problem.n_free}) for {problem.n_joints} joints and "
            f"degree {problem.degree}, got shape {x.shape}"
        )
    if not isinstance(x, jax.core.Tracer) and not np.all(np.isfinite(x)):
        raise ValueError(f"x must be finite, got non-finite values in {x!r}")
    return x


def fitness(problem: Problem, x) -> jax.Array:
    """Paper eq. 17: 0 if any link collides, else 1 / (sum of joint travelling distances).

    Args:
      problem: the problem (its ``collision`` mode decides what colliding means).
      x: free parameters, shape (..., n_free).

    Returns:
      Array of shape (...,).

    Example:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> float(jaxarm.fitness(problem, [66.7388, -28.1028, -9.8855]))  # doctest: +ELLIPSIS
      0.1946...
    """
    return _evaluated(problem, x).fitness


def violation(problem: Problem, x) -> jax.Array:
    """How much a path collides (cm: the deepest penetration found, see ``jaxarm.collision``
    and ``jaxarm.certified``).

    Args:
      x: free parameters, shape (..., n_free).

    Returns:
      Array of shape (...,), >= 0 and exactly 0 iff the path is collision-free.
    """
    return _evaluated(problem, x).violation


def collides(problem: Problem, x) -> jax.Array:
    """Whether any link overlaps any obstacle, in the problem's collision mode; shape (...,)."""
    return violation(problem, x) > 0


@functools.partial(jit, static_argnums=(0, 1), storable=True)
def _travelling_distance(degree: int, n_samples: int, start, goal, rows):
    """``path.travelling_distance`` of rows (B, n_free) -> (B,), compiled."""
    return path.travelling_distance(start, goal, rows, degree, n_samples)


def travelling_distance(problem: Problem, x) -> jax.Array:
    """Joint angle travelling distance summed over joints (paper eq. 5, Simpson); shape (...,).

    A program of its own, without the collision check: the same values as ``evaluate``'s
    ``distance`` (tested bit for bit).
    """
    return on_padded_rows(functools.partial(_travelling_distance, problem.degree,
                                            problem.n_samples, problem.arrays.start,
                                            problem.arrays.goal), _as_params(problem, x))


def joint_path(problem: Problem, x, r, order: int = 0) -> jax.Array:
    """Joint angles (or their ``order``-th derivative with respect to r) along a path, computed
    by one compiled program per shape of x and r.

    Args:
      x: free parameters, shape (..., n_free).
      r: normalised times in [0, 1], shape (n_r,).
      order: derivative order, 0 to 3.

    Returns:
      Array of shape (..., n_r, n_joints).
    """
    x = _as_params(problem, x)
    if isinstance(order, bool) or order not in range(4):
        raise ValueError(f"order must be 0, 1, 2 or 3, got {order!r}")
    if not isinstance(r, jax.Array):
        r = np.asarray(r, dtype=np.float64)
        if r.ndim != 1 or not np.all((r >= 0.0) & (r <= 1.0)):
            raise ValueError(f"r must be a 1-D array of normalised times in [0, 1], got {r!r}")
    basis = path.basis_values(problem.degree, r, order)
    return _joint_angles(problem.arrays.start, problem.arrays.goal, x, basis, order=order)


# One program per shape: run op by op, a call with a new shape compiled 8-12 small programs
# (0.34-0.41 s, against 0.07-0.09 s compiled whole, in a fresh process).
_joint_angles = jit(path.joint_angles, static_argnames="order")


def coefficients(problem: Problem, x) -> jax.Array:
    """All polynomial coefficients ``a_0 .. a_d`` per joint (paper eq. 10 for degree 6).

    Returns:
      Array of shape (..., n_joints, degree + 1), ascending powers.
    """
    x = _as_params(problem, x)
    return path.coefficients(problem.arrays.start, problem.arrays.goal, x, problem.degree)


class Certificate(NamedTuple):
    """The certified check's verdict on paths (``certify``), each field of shape (...,)."""

    free: jax.Array  # bool: proved to keep the margin from every obstacle for all r in [0, 1]
    colliding: jax.Array  # bool: some tested time breaks the margin (never both)
    clearance: jax.Array  # cm: a lower bound on the motion's smallest distance to an obstacle
    #   when free (>= margin); the smallest distance found (< margin; negative: penetration
    #   depth) when colliding; the smallest distance bound seen otherwise
    exhausted: jax.Array  # bool: neither, because the check's budget ran out


def certify(problem: Problem, x) -> Certificate:
    """Prove paths collision-free for every r in [0, 1], or find where they collide.

    Whatever the problem's ``collision`` mode, this runs the certified check: a motion whose
    clearance exceeds ``problem.margin`` by at least ``problem.certify_tol`` everywhere is
    ``free``; one that comes closer than the margin at some tested time is ``colliding``; in
    between (within the tolerance of the margin), or when the budget runs out, neither.
    With ``problem.joint_limits``, ``free`` also needs every joint proved inside its range and
    an angle found outside makes the path ``colliding`` (``clearance`` stays the obstacles').
    The batch is padded to ``padded_size`` paths (copies of its first path), so a few
    compiled programs serve every batch size; no path's verdict depends on the others in its
    batch.

    Args:
      problem: the problem.
      x: free parameters, shape (..., n_free).

    Returns:
      ``Certificate`` of arrays of shape (...,).

    Example:
      >>> problem = jaxarm.load_scenario("paper-case-2")
      >>> certificate = jaxarm.certify(problem, [66.7388, -28.1028, -9.8855])
      >>> bool(certificate.free), bool(certificate.colliding)
      (True, False)
    """
    spec = problem.spec._replace(collision="certified")
    return on_padded_rows(functools.partial(_evaluate_and_certify, spec, problem.arrays),
                          _as_params(problem, x))[1]
