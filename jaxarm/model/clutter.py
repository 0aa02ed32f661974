"""Cluttered scenes on demand: random obstacles within an arm's reach, its start and goal clear.

``clutter(problem, count, kind, size, seed)`` adds ``count`` obstacles of one kind to a
problem's world: centres uniform over the disk of the arm's reach (by area), sizes (the
circumradius, cm) uniform in ``size``, each kept at least the problem's margin from every link
at the start and the goal (tested on the obstacle's circumscribed circle, so a little
further). With ``clear_path``, also from the arm along that path, so that the scene has a
collision-free motion. The same seed gives the same world.
"""

from __future__ import annotations

import numpy as np

from jaxarm._validate import check_seed, finite_vector, positive_int
from jaxarm.choices import CLUTTER_KINDS, one_of
from jaxarm.model.problem import MAX_SLOTS, Problem, check_problem
from jaxarm.model.world import OBSTACLE_KINDS, World

CLEAR_PATH_SAMPLES = 1001  # instants of ``clear_path`` kept clear
# Draws per obstacle before giving up: a scene whose postures leave too little room fails
# with a message instead of looping.
_TRIES_PER_OBSTACLE = 1000


def clutter(problem: Problem, count: int, kind: str = "circles", size=(1.0, 3.0),
            seed: int = 0, clear_path=None) -> Problem:
    """The problem with ``count`` random obstacles added to its world.

    Args:
      problem: the arm, its start and goal, and any obstacles it already has.
      count: obstacles to add, >= 1 (with the world's own of the kind's slots, circles or
        polygons, at most ``MAX_SLOTS``).
      kind: ``"circles"``, ``"triangles"`` (convex, vertices at random angles on the
        circumcircle) or ``"boxes"`` (axis-aligned squares).
      size: ``(smallest, largest)`` circumradius, cm, 0 < smallest <= largest.
      seed: the random stream (an int >= 0).
      clear_path: optional free parameters of a path, shape (n_free,), kept clear too (at
        ``CLEAR_PATH_SAMPLES`` instants, with a spare of twice the farthest any link end moves
        between two of them): then a collision-free motion exists. ``0`` stands for zeros,
        the path with no free coefficients.

    Returns:
      A ``Problem`` named ``"<name>+<count> <kind>"``.

    Raises:
      ValueError: naming the argument, or saying that the obstacles do not fit beside the
        start and goal postures.

    Examples:
      >>> problem = jaxarm.load_scenario("open-space")
      >>> jaxarm.clutter(problem, 40, "triangles", size=(1.0, 2.0), seed=1).world.n_obstacles
      40
    """
    check_problem(problem)
    one_of("kind", kind, CLUTTER_KINDS)
    count = positive_int("count", count, minimum=1)
    # boxes and triangles take polygon slots; the world's own of that kind
    slot, index = ("circle", 0) if kind == "circles" else ("polygon", 1)
    slots = problem.world.capacities()[index]
    if count > MAX_SLOTS - slots:
        raise ValueError(f"count must be <= {MAX_SLOTS - slots} (a world holds {MAX_SLOTS} "
                         f"{slot} slots and {problem.name!r} fills {slots}), got {count}")
    low, high = (float(v) for v in finite_vector("size", size, length=2))
    if not 0 < low <= high:
        raise ValueError(f"size must be (smallest, largest) with 0 < smallest <= largest (cm), "
                         f"got {tuple(size)!r}")
    rng = np.random.default_rng(check_seed(seed))
    reach = problem.arm.reach
    postures = [problem.start, problem.goal]
    spare = 0.0
    if clear_path is not None:
        postures, spare = _path_postures(problem, clear_path)
    links = np.concatenate([_posture_links(problem.arm.lengths, posture)
                            for posture in postures])
    centres, radii = [], []
    tries = 0
    while len(centres) < count:
        tries += 1
        if tries > _TRIES_PER_OBSTACLE * count:
            raise ValueError(
                f"cannot place {count} {kind} of size {low:g}-{high:g} cm clear of the start "
                f"and goal of {problem.name!r} (placed {len(centres)}); ask for fewer or smaller")
        distance = reach * np.sqrt(rng.uniform())
        angle = rng.uniform(0.0, 2.0 * np.pi)
        centre = distance * np.array([np.cos(angle), np.sin(angle)])
        radius = rng.uniform(low, high)
        if _segment_distances(centre, links).min() > radius + problem.margin + spare:
            centres.append(centre)
            radii.append(radius)
    added = _shapes(kind, np.array(centres), np.array(radii), rng)
    world = problem.world
    grown = World(**{kind: getattr(world, kind) + getattr(added, kind)
                     for kind in OBSTACLE_KINDS})
    return problem.replace(world=grown, capacities=None, name=f"{problem.name}+{count} {kind}",
                           description=f"{problem.name} with {count} random {kind} of size "
                           f"{low:g}-{high:g} cm (seed {seed})")


def _path_postures(problem: Problem, clear_path):
    """The postures along a path to keep clear, and the spare (cm) that covers the motion
    between two of them."""
    from jaxarm.model.path_functions import joint_path

    if np.ndim(clear_path) == 0 and not isinstance(clear_path, str):
        if isinstance(clear_path, (bool, np.bool_)) or clear_path != 0:
            raise ValueError(f"clear_path must be 0 (the path with no free coefficients) or "
                             f"{problem.n_free} numbers, got {clear_path!r}")
        clear_path = np.zeros(problem.n_free)
    x = finite_vector("clear_path", clear_path, problem.n_free)
    r = np.linspace(0.0, 1.0, CLEAR_PATH_SAMPLES)
    postures = np.asarray(joint_path(problem, x.astype(np.float32), r), dtype=np.float64)
    ends = np.stack([_posture_links(problem.arm.lengths, p)[:, 2:] for p in postures])
    step = np.linalg.norm(np.diff(ends, axis=0), axis=-1).max()
    return list(postures), 2.0 * float(step)


def _posture_links(lengths, theta) -> np.ndarray:
    """Every link's end points at one posture, shape (n_links, 4) as (sx, sy, ex, ey)."""
    absolute = np.cumsum(np.asarray(theta, dtype=np.float64))
    ends = np.cumsum(np.stack([np.asarray(lengths) * np.cos(absolute),
                               np.asarray(lengths) * np.sin(absolute)], axis=1), axis=0)
    starts = np.concatenate([np.zeros((1, 2)), ends[:-1]])
    return np.concatenate([starts, ends], axis=1)


def _segment_distances(point, links) -> np.ndarray:
    """Distance from a point (2,) to segments (n, 4) as (sx, sy, ex, ey)."""
    start, end = links[:, :2], links[:, 2:]
    along = end - start
    t = np.clip(np.sum((point - start) * along, axis=1)
                / np.maximum(np.sum(along * along, axis=1), 1e-30), 0.0, 1.0)
    return np.linalg.norm(point - (start + t[:, None] * along), axis=1)


def _shapes(kind: str, centres, radii, rng) -> World:
    """Obstacles of one kind inscribed in the circles (centres (n, 2), radii (n,))."""
    if kind == "circles":
        return World(circles=[(float(x), float(y), float(r))
                              for (x, y), r in zip(centres, radii)])
    if kind == "boxes":
        half = radii / np.sqrt(2.0)
        return World(boxes=[((float(x - h), float(y - h)), (float(x + h), float(y + h)))
                            for (x, y), h in zip(centres, half)])
    # Triangles: three angles at least 0.6 rad apart, so none is a sliver.
    triangles = []
    for centre, radius in zip(centres, radii):
        gaps = 0.6 + rng.dirichlet(np.ones(3)) * (2.0 * np.pi - 1.8)
        angles = rng.uniform(0.0, 2.0 * np.pi) + np.cumsum(gaps)
        triangles.append([(float(centre[0] + radius * np.cos(a)),
                           float(centre[1] + radius * np.sin(a))) for a in angles])
    return World(polygons=triangles)
