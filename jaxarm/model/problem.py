"""The planning problem: an arm, its start and goal postures, the obstacles, the path settings.

A ``Problem`` splits into a static ``ProblemSpec`` (sizes and modes: what a compiled program
depends on) and ``ProblemArrays`` (angles, lengths, obstacles: data), so problems that differ
only in data share one compiled program. What is computed of its paths lives in
``jaxarm.checks`` (fitness, violation, certify) and ``jaxarm.model.path_functions``.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import pathlib
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm._validate import (
    MAX_CM,
    angles_outside,
    finite_scalar,
    finite_vector,
    joint_limit_pairs,
    positive_int,
    representable,
)
from jaxarm.choices import COLLISION_MODES, MAX_SAMPLES, one_of
from jaxarm.model import nearby, path, posture, self_collision
from jaxarm.model.arm import Arm
from jaxarm.model.world import World, WorldArrays

# Pieces per path the certified check may test: it counts them in an int32 it shares with
# three flags, and a path can test a few more than its budget.
MAX_CERTIFY_BUDGET = 2**27
# Obstacle slots of each kind (circles, polygons, vertices per polygon): every slot is computed
# for every link at every sample, so a scene needs far fewer; a bound that stops a typo such as
# 10**9 before it allocates gigabytes.
MAX_SLOTS = 2**16


@functools.partial(jit, storable=True)
def _posture_depth(lengths, world: WorldArrays, theta):
    """``posture.penetration`` at one posture, (n_joints,) -> (n_joints, n_slots), compiled:
    a Problem checks its start and goal on construction. The lengths are data and the world is
    packed at ``_posture_capacities``, so that problems of as many joints share the program."""
    return posture.penetration(lengths, world, theta)


_posture_separation = functools.partial(jit, storable=True)(posture.separation)


def _posture_capacities(capacities: tuple[int, int, int]) -> tuple[int, int, int]:
    """Slots for the posture checks: at least 4 circles, 4 polygons and 8 vertices, so that
    the shipped scenes of one arm share one program (it checks a single posture)."""
    circles, polygons, vertices = capacities
    return max(circles, 4), max(polygons, 4), max(vertices, 8)


def _posture_parts(world: World, capacities: tuple[int, int, int]):
    """The world in parts for the posture checks, each with the capacities to pack it at: a
    large world (``nearby.uses_broad_phase``) in parts of ``nearby.BLOCK`` obstacles of one
    kind, which share one program whatever the world's size."""
    if not nearby.uses_broad_phase(capacities):
        return [(world, _posture_capacities(capacities))]
    size, parts = nearby.BLOCK, []
    parts_capacities = (size, size, max(capacities[2], 8))
    for kind in ("circles", "boxes", "polygons"):
        obstacles = getattr(world, kind)
        for first in range(0, len(obstacles), size):
            part = World(**{kind: obstacles[first:first + size]})
            parts.append((_Renamed(part, kind, first), parts_capacities))
    return parts


class _Renamed(NamedTuple):
    """A part of a world whose slot names are the whole world's (``_posture_parts``)."""

    part: World
    kind: str
    first: int

    def pack(self, capacities):
        return self.part.pack(capacities)

    def slot_names(self, capacities):
        return [None if name is None else
                f"{self.kind}[{self.first + int(name.split('[')[1][:-1])}]"
                for name in self.part.slot_names(capacities)]


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
      start: joint angles (rad) at r = 0, shape (n_joints,).
      goal: joint angles (rad) at r = 1, shape (n_joints,).
      world: the obstacles.
      degree: polynomial degree d, 6 to ``MAX_DEGREE`` (d - 5 free coefficients per joint).
      n_samples: odd number of points of r in [0, 1] for Simpson's rule and the sampled check,
        at most ``MAX_SAMPLES`` (100,001).
      collision: ``"certified"`` (default: every r in [0, 1] proved free, see
        ``jaxarm.checks.certified``) or ``"sampled"`` (the paper's check at the n samples only).
      init_low: low end of the range the initial swarm is drawn from, a scalar or shape
        (n_free,), within +-``MAX_COEFFICIENT`` (1e4).
      init_high: high end of that range, the same way.
      name: the problem's name in reports.
      description: one line for reports.
      capacities: obstacle slots (circles, polygons, vertices per polygon); default from world.
      margin: clearance (cm) every link must keep from every obstacle; 0 allows grazing. Like
        every length and coordinate, at most ``MAX_CM`` (1e5 cm, float32 geometry).
      certify_tol: the certified check's tolerance (cm): every motion whose clearance exceeds
        the margin by at least this much is certified free.
      certify_budget: pieces the certified check tests per path before it splits no more: a
        piece that needs splitting after that makes the path exhausted (it counts as
        colliding, and ``certify`` reports it). Pieces that need no split are still tested,
        so a path may test a few more. At most ``2**27``.
      joint_limits: one ``(low, high)`` pair per joint (rad), or None. A path that leaves a
        range at any r counts as colliding (see ``jaxarm.checks.joint_limits``: at the samples in
        sampled mode, for every r in certified mode).

    Raises:
      ValueError: naming the field and value, including a start or goal posture that collides.

    Examples:
      >>> arm = jaxarm.Arm((30.0, 30.0, 20.0))
      >>> problem = jaxarm.Problem(arm=arm, start=[0.0, 0.5, 0.5], goal=[1.0, 0.5, 0.5])
      >>> problem.n_free, problem.collision
      (3, 'certified')
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
        degree = positive_int("degree", self.degree, minimum=path.MIN_DEGREE,
                              maximum=path.MAX_DEGREE)
        set_field("degree", degree)
        n_samples = positive_int("n_samples", self.n_samples, minimum=3, maximum=MAX_SAMPLES)
        if n_samples % 2 == 0:
            raise ValueError(f"n_samples must be odd for Simpson's rule, got {n_samples}")
        one_of("collision", self.collision, COLLISION_MODES)
        set_field("margin", finite_scalar("margin", self.margin))
        if self.margin < 0:
            raise ValueError(f"margin must be >= 0 (cm), got {self.margin!r}")
        representable("margin", self.margin, MAX_CM, " cm")
        set_field("certify_tol", finite_scalar("certify_tol", self.certify_tol))
        if self.certify_tol <= 0:
            raise ValueError(f"certify_tol must be > 0 (cm), got {self.certify_tol!r}")
        representable("certify_tol", self.certify_tol, MAX_CM, " cm")
        set_field("certify_budget", positive_int("certify_budget", self.certify_budget,
                                                 minimum=1, maximum=MAX_CERTIFY_BUDGET))
        low, high = (self._bound(name) for name in ("init_low", "init_high"))
        set_field("init_low", low)
        set_field("init_high", high)
        bad = np.nonzero(~(np.asarray(self.bounds()[0]) < np.asarray(self.bounds()[1])))[0]
        if bad.size:
            at = "" if np.ndim(low) == np.ndim(high) == 0 else f" at coefficient {int(bad[0])}"
            raise ValueError(f"init_low must be < init_high{at}, got {low!r} and {high!r}")
        if self.joint_limits is not None:
            set_field("joint_limits", joint_limit_pairs(self.joint_limits, self.n_joints))
            for which in ("start", "goal"):
                for joint, angle in angles_outside(self.joint_limits, getattr(self, which)):
                    low, high = self.joint_limits[joint]
                    raise ValueError(f"{which} joint {joint + 1} is {angle!r} rad, outside "
                                     f"joint_limits[{joint}] = ({low!r}, {high!r})")
        set_field("capacities", _capacities(self.capacities, self.world))
        self._check_postures()

    def _bound(self, name: str):
        value = getattr(self, name)
        if np.ndim(value) == 0:
            return representable(name, finite_scalar(name, value), MAX_COEFFICIENT)
        return tuple(representable(name, finite_vector(name, value, self.n_free),
                                   MAX_COEFFICIENT).tolist())

    def _check_postures(self) -> None:
        """Start, then goal: neither may overlap an obstacle or come closer than the margin."""
        dtype = jnp.result_type(float)
        lengths = np.asarray(self.arm.lengths, dtype=dtype)
        parts = [(part.pack(capacities), part.slot_names(capacities))
                 for part, capacities in _posture_parts(self.world, self.capacities)]
        for which in ("start", "goal"):
            theta = np.asarray(getattr(self, which), dtype=dtype)
            for world, names in parts:
                self._check_posture(which, theta, lengths, world, names)
            if self.arm.self_collision:
                self._check_self_collision(which, theta, lengths)

    def _check_self_collision(self, which: str, theta, lengths) -> None:
        """Links that are not neighbours neither cross nor come closer than the margin
        (``self_collision.posture_pair_separations``)."""
        separation = self_collision.posture_pair_separations(lengths, theta)
        if separation.size == 0:  # one or two links: no pair to meet
            return
        closest = int(np.argmin(separation))
        if separation[closest] < self.margin:
            i, j = self_collision.pairs(self.n_joints)[closest]
            pair = f"links {i + 1} and {j + 1}"
            raise ValueError(
                f"{which} posture {list(getattr(self, which))} collides with itself: "
                + (f"{pair} cross (by {-separation[closest]:.4g} cm)" if separation[closest] < 0
                   else f"{pair} are {separation[closest]:.4g} cm apart, closer than margin "
                        f"{self.margin:g} cm"))

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
            world=self._packed_world(),
            margin=np.asarray(self.margin),
            certify_tol=np.asarray(self.certify_tol),
            joint_limits=np.asarray(self.joint_limits if self.joint_limits is not None
                                    else [(-np.inf, np.inf)] * self.n_joints),
        )

    def device_arrays(self) -> ProblemArrays:
        """``arrays`` on JAX's default device, placed once per setting of ``jax_enable_x64``:
        a compiled call given NumPy arrays copies them to the device at every call (the near
        tables of a world of 1,000 circles are about 34 MB), converted as
        ``jax.device_put`` converts them (float64 to float32 unless x64 is on), so either
        gives the same bits. For the package's compiled calls from the host; placed eagerly
        even when first asked for inside a trace. With several devices (or processes), the
        NumPy ``arrays`` themselves, which a compiled call places where its sharding needs
        them. The placed arrays live as long as the problem, and are not pickled with it."""
        if jax.device_count() > 1:
            return self.arrays
        placed = self.__dict__.setdefault("_device_arrays", {})  # frozen: no __setattr__
        x64 = bool(jax.config.jax_enable_x64)
        if x64 not in placed:
            with jax.ensure_compile_time_eval():  # never a tracer of a caller's jit
                placed[x64] = jax.device_put(self.arrays)
        return placed[x64]

    def __getstate__(self) -> dict:
        """The problem's fields and host arrays, without its device arrays."""
        state = dict(self.__dict__)
        state.pop("_device_arrays", None)
        return state

    def _packed_world(self) -> WorldArrays:
        """The world packed at the problem's capacities, with near tables for this arm and
        margin when it is large (``jaxarm.model.nearby``)."""
        world = self.world.pack(self.capacities)
        if self.arm.self_collision and self.n_joints >= 3:  # two links have no pair to check
            world = world._replace(link_walls=self_collision.link_walls(self.arm.lengths))
        if not nearby.uses_broad_phase(self.capacities):
            return world
        lengths = np.asarray(self.arm.lengths)
        if nearby.reads_every_slot(self.capacities):
            return world._replace(near=nearby.every_slot(world, lengths, self.collision))
        certified = self.collision == "certified"
        return world._replace(near=nearby.build(
            world, lengths, nearby.reach_candidates(lengths, self.margin, certified),
            self.collision))

    def replace(self, **changes) -> "Problem":
        """A copy with some fields changed (and validated again); a ValueError naming a field
        ``Problem`` does not have."""
        fields = [field.name for field in dataclasses.fields(self) if field.init]
        for name in changes:
            if name not in fields:
                close = difflib.get_close_matches(name, fields, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else f"; its fields: {fields}"
                raise ValueError(f"Problem has no field {name!r}{hint}")
        return dataclasses.replace(self, **changes)

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
                f"{len(world.polygons)} polygons"
                + (f", {len(world.segments)} segments" if world.segments else ""),
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
# The initial range's ends: a degree-6 coefficient a swings its joint by up to |a| / 64 rad
# (g_6 = r^3 (r - 1)^3), so 1e4 starts the swarm within about MAX_ANGLE of the ends; from a
# range of 1e10 the sampled check called a path that turns 1e8 rad collision-free.
MAX_COEFFICIENT = 1e4


def share_capacities(problems) -> list[Problem]:
    """The problems with one set of obstacle capacities per arm, so that they share compiled
    programs: each gets, slot kind by slot kind, the largest capacities among the problems
    with the same number of joints.

    A search compiles once per capacities (with the arm, degree and check), and compiling is
    most of a short study's time. Padded slots are empty but still computed, so a small scene
    runs slower than at its own capacities ("Shared capacities in the report's suite" in
    ``benchmarks/RESULTS.md``, *Decisions and negative results*); its results are as valid,
    though not always bit for bit the same (another compiled program can round differently in
    the last bits).
    ``reproduce-paper`` uses it for its suite's free shares and its degree comparison.

    Args:
      problems: ``Problem``s.

    Returns:
      The problems, in order, each with its arm's shared ``capacities``.

    Examples:
      >>> from jaxarm import load_scenario
      >>> [p.capacities for p in share_capacities(
      ...     [load_scenario("paper-case-1"), load_scenario("death-trap")])]
      [(8, 1, 4), (8, 1, 4)]
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


def _capacities(value, world: World) -> tuple[int, int, int]:
    """``value`` (or the world's default) as three slot counts that hold ``world``, each at most
    ``MAX_SLOTS``, or a ValueError naming ``capacities``."""
    capacities = world.capacities() if value is None else value
    try:
        counts = tuple(capacities)
    except TypeError:
        counts = ()
    if len(counts) != 3:
        raise ValueError(f"capacities must be 3 slot counts (circles, polygons, vertices per "
                         f"polygon), got {value!r}")
    for index, count in enumerate(counts):
        positive_int(f"capacities[{index}]", count, minimum=0, maximum=MAX_SLOTS)
    world.pack(counts)  # raises if the capacities are too small
    return tuple(int(c) for c in counts)


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


def check_problem(problem) -> Problem:
    """``problem``, or a ValueError saying what it is instead (a scenario's name: how to load
    it)."""
    if isinstance(problem, Problem):
        return problem
    if isinstance(problem, (str, pathlib.PurePath)):
        raise ValueError(f"problem must be a jaxarm.Problem, got {str(problem)!r}: load a "
                         f"scenario with jaxarm.load_scenario({str(problem)!r})")
    raise ValueError(f"problem must be a jaxarm.Problem, got {type(problem).__name__}")


def as_params(problem: Problem, x) -> jax.Array:
    check_problem(problem)
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

