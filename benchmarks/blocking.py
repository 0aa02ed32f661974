"""Obstacles that block the paths better than any the paper's runs found.

The paper's best case-1 path has fitness 0.1774; a reconstructed layout that leaves much better
paths free lets escaped swarms climb far above the paper's runs. A circle can block a path while
every published path stays free only where that path leaves the region the published motions
sweep: at some sample, a point of one of its links lies farther than the gap from every published
link at every time (``sweep_excursion``). There ``block_paths`` places the largest circle that
keeps the gap from the published sweep, until every path given to it collides.
``free_paths_above`` looks for such paths (a grid and the default search), ``block_better_paths``
alternates the two, and ``prove_blocked`` shows by branch and bound that none is left: every
path above a threshold collides at a sample. ``reconstruct_scenarios.py`` beside it runs them on
case 1 (``tests/test_blocking.py`` imports this file by its path).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm.checks.evaluate import fitness
from jaxarm.choices import DEFAULT_METHODS
from jaxarm.model import path
from jaxarm.model.arm import joint_positions
from jaxarm.model.problem import Problem
from jaxarm.model.world import slot_capacity


def motion_segments(problem: Problem, x, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Segments that outline what the motions sweep, in float64: every link at ``n_points``
    equally spaced times, and the path of every joint and of the end-effector from one time
    to the next (the sides of the strip a link sweeps between two times, which the link's
    positions alone would leave open; the strip's inside is not covered, which dense times
    make negligible).

    Args:
      x: free parameters, shape (n_paths, n_free).

    Returns:
      ``(a, b)``: segment end points, each of shape (n_segments, 2), cm.
    """
    positions = _joint_positions_64(problem, x, np.linspace(0.0, 1.0, n_points))
    links = (positions[:, :, :-1], positions[:, :, 1:])  # (paths, times, links, 2)
    traces = (positions[:, :-1, 1:], positions[:, 1:, 1:])  # every joint from one time to the next
    a = np.concatenate([links[0].reshape(-1, 2), traces[0].reshape(-1, 2)])
    b = np.concatenate([links[1].reshape(-1, 2), traces[1].reshape(-1, 2)])
    return a, b


def _joint_positions_64(problem: Problem, x, r) -> np.ndarray:
    """Joint positions (base first) in float64 NumPy, shape (n_paths, len(r), n_joints + 1, 2).

    NumPy rather than the package's JAX kinematics under x64: paper-case-1's circles were
    picked with this one, and the picks moved when both it and the slot counts of
    ``block_paths`` were changed (which of the two moved them was not tested)."""
    x = np.asarray(x, np.float64).reshape(-1, problem.n_free)
    polynomial = path.polynomial_coefficients(np.asarray(problem.start, np.float64),
                                              np.asarray(problem.goal, np.float64), x,
                                              problem.degree)
    theta = polynomial @ (np.asarray(r, np.float64)[:, None] ** np.arange(problem.degree + 1)).T
    absolute = np.cumsum(theta.transpose(0, 2, 1), axis=-1)  # (paths, times, joints)
    steps = np.asarray(problem.arm.lengths) * np.stack([np.cos(absolute), np.sin(absolute)], -1
                                                       ).transpose(3, 0, 1, 2)
    joints = np.cumsum(steps, axis=-1).transpose(1, 2, 3, 0)  # (paths, times, joints, 2)
    return np.concatenate([np.zeros(joints.shape[:2] + (1, 2)), joints], axis=2)


@jit
def _nearest_distances(points, a, b):  # float32, or float64 under jax.enable_x64
    """Distance from each point to the nearest segment, shape (n_points,)."""
    ab = b - a
    length2 = jnp.maximum(jnp.sum(ab * ab, -1), 1e-30)

    def one(p):
        t = jnp.clip(jnp.sum((p[None] - a) * ab, -1) / length2, 0.0, 1.0)
        return jnp.sqrt(jnp.min(jnp.sum((a + t[:, None] * ab - p[None]) ** 2, -1)))

    return jax.lax.map(one, points, batch_size=64)


def nearest_distances(points, segments, *, exact: bool = False,
                      chunk: int = 1 << 15) -> np.ndarray:
    """Distance from each point to the nearest of ``segments``, cm: in float32, or in float64
    with ``exact``.

    Args:
      points: shape (n_points, 2), cm.
      segments: ``(a, b)``, end points, each of shape (n_segments, 2), cm.
      exact: float64 instead of float32.
      chunk: segments per compiled call.

    Returns:
      Shape (n_points,).
    """
    points = np.asarray(points, np.float64).reshape(-1, 2)
    a, b = (np.asarray(s, np.float64) for s in segments)
    if not len(points):
        return np.zeros(0)
    chunk = min(chunk, 1 << int(np.ceil(np.log2(max(len(a), 1)))))
    best = np.full(len(points), np.inf)
    with jax.enable_x64(exact):
        for start in range(0, len(a), chunk):  # segments in chunks of one padded size
            part_a, part_b = a[start:start + chunk], b[start:start + chunk]
            pad = chunk - len(part_a)
            part_a = np.concatenate([part_a, np.repeat(part_a[:1], pad, 0)])
            part_b = np.concatenate([part_b, np.repeat(part_b[:1], pad, 0)])
            found = _nearest_distances(jnp.asarray(points), jnp.asarray(part_a),
                                       jnp.asarray(part_b))
            best = np.minimum(best, np.asarray(found, np.float64))
    return best


def sweep_excursion(problem: Problem, x, keep_free, *, n_times: int | None = None,
                    n_points: int = 2001, n_along: int = 9, exact: bool = False):
    """How far each motion leaves the region the ``keep_free`` motions sweep.

    Per path, the largest distance from a point of its links (``n_along`` points per link, at
    ``n_times`` equally spaced times, default the problem's samples) to the ``keep_free``
    motions (``motion_segments`` at ``n_points`` times), and that point. An obstacle that
    keeps a gap from the ``keep_free`` motions can block a path at those times only if the
    excursion exceeds the gap: a path that never leaves by more than the gap stays free.

    Args:
      x: free parameters, shape (n_paths, n_free).
      exact: distances in float64 (else float32, enough to rank points).

    Returns:
      ``(excursion, point)``: shapes (n_paths,) cm and (n_paths, 2).
    """
    keep = motion_segments(problem, keep_free, n_points)
    times = np.linspace(0.0, 1.0, n_times or problem.n_samples)
    along = np.linspace(0.0, 1.0, n_along)[:, None]
    excursion, points = [], []
    for joints in _joint_positions_64(problem, x, times):  # one path at a time: (times, j, 2)
        links = (joints[:, :-1, None] * (1 - along) + joints[:, 1:, None] * along).reshape(-1, 2)
        distance = nearest_distances(links, keep, exact=exact)
        excursion.append(distance.max())
        points.append(links[np.argmax(distance)])
    return np.array(excursion), np.array(points).reshape(-1, 2)


class ObstacleLayout(NamedTuple):
    """Circles chosen by ``block_paths`` and what each achieved."""

    circles: tuple  # of (x, y, radius), cm
    seeds: np.ndarray  # shape=(n_circles, 2): the sweep point each circle was placed at
    blocked: np.ndarray  # shape=(n_circles,), int: ``block`` paths colliding after each
    n_block: int  # how many paths had to be blocked


def with_circles(problem: Problem, circles, capacities=None) -> Problem:
    """``problem`` with ``circles`` ((x, y, radius) each, cm) added to its world (capacities
    recomputed unless given)."""
    world = problem.world
    circles = tuple(tuple(float(v) for v in c) for c in circles)
    return problem.replace(world=dataclasses.replace(world, circles=world.circles + circles),
                           capacities=capacities)


def _circles_through(point, keep, gap: float) -> list[tuple[float, float, float]]:
    """Circles that hold ``point`` (x, y) and keep ``gap`` from the segments ``keep`` (``(a,
    b)``, each of shape (n_segments, 2)): centres moved from the point away from the nearest
    segment (and 20 degrees either side) by 0 to 64 cm, each as large as the gap allows; a list
    of (x, y, radius)."""
    a, b = keep
    ab = b - a
    t = np.clip(np.sum((point - a) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-30), 0, 1)
    nearest = a + t[:, None] * ab
    i = int(np.argmin(np.linalg.norm(nearest - point, axis=-1)))
    away = (point - nearest[i]) / np.linalg.norm(point - nearest[i])
    centres = []
    for angle in np.radians([0.0, -20.0, 20.0]):
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        direction = rotation @ away
        centres += [point + step * direction for step in (0.0, 0.5, 1, 2, 4, 8, 16, 32, 64)]
    centres = np.array(centres)
    radii = nearest_distances(centres, keep, exact=True) - gap
    inside = radii > np.linalg.norm(centres - point, axis=-1)
    return [(float(c[0]), float(c[1]), float(r)) for c, r in zip(centres[inside], radii[inside])]


def block_paths(problem: Problem, keep_free, block, *, gap: float = 0.05,
                max_obstacles: int = 6, n_points: int = 2001, n_probe: int = 12,
                tries: int = 4, seed: int = 0, log=None) -> ObstacleLayout:
    """Circles, added to ``problem``'s obstacles, that make every ``block`` path collide while
    every point of the ``keep_free`` motions stays ``gap`` clear of them.

    A path can be blocked so only if it leaves the region the ``keep_free`` motions sweep by
    more than the gap. Each step takes up to ``n_probe`` of the ``block`` paths still free and
    finds on each the point of its sweep (at the problem's samples) farthest from the
    ``keep_free`` motions (``sweep_excursion``). Around the ``tries`` farthest such points it
    places candidates: circles holding the point, as large as the gap allows, centred 0 to
    64 cm away from the nearest kept motion. The candidate that blocks the most paths still
    free is added; it stops when every path collides (in the problem's collision mode) or
    after ``max_obstacles``.

    Args:
      problem: the problem to add circles to.
      keep_free: free parameters that must stay free, shape (n_keep, n_free).
      block: free parameters that must collide, shape (n_block, n_free).
      gap: clearance kept from the ``keep_free`` motions, cm.
      max_obstacles: circles added at most.
      n_points: times at which the kept motions are measured.
      n_probe: paths probed per step.
      tries: sweep points tried per step.
      seed: picks the probed paths.
      log: called with a line of text after each circle (None: silent).

    Returns:
      ``ObstacleLayout``; ``with_circles(problem, layout.circles)`` is the new problem.
    """
    keep = motion_segments(problem, keep_free, n_points)
    block = np.asarray(block, np.float64).reshape(-1, problem.n_free)
    world = problem.world
    # one capacity for every trial: a new layout is new data, not a new program
    # At least 4 polygon and vertex slots even for circles only: paper-case-1's circles were
    # picked so (see _joint_positions_64).
    n_polygons, n_vertices = world.capacities()[1:]
    capacities = (slot_capacity(len(world.circles) + max_obstacles), max(4, n_polygons),
                  max(4, n_vertices))
    rng = np.random.default_rng(seed)
    circles, seeds, blocked = [], [], []
    current = problem.replace(capacities=capacities)
    for _ in range(max_obstacles):
        open_ = np.flatnonzero(np.asarray(fitness(current, block)) > 0)
        if not open_.size:
            break
        probe = block[rng.permutation(open_)[:n_probe]]
        # on each probed path, the sweep point farthest from the kept motions, ranked against
        # the kept sweep at the problem's samples (its sides included, it is close enough to
        # the exact one; circles are placed against ``keep``)
        farthest = zip(*sweep_excursion(problem, probe, keep_free,
                                        n_points=min(n_points, problem.n_samples)))
        candidates = sorted((c for c in farthest if c[0] > 1.5 * gap), key=lambda c: -c[0])
        best = None
        for _, point in candidates[:tries]:
            for circle in _circles_through(point, keep, gap):
                trial = with_circles(current, [circle], capacities)
                count = int(np.sum(np.asarray(fitness(trial, block[open_])) == 0))
                if best is None or count > best[0]:
                    best = (count, circle, point, trial)
        if best is None or best[0] == 0:
            break
        circles.append(best[1])
        seeds.append(best[2])
        current = best[3]
        blocked.append(int(np.sum(np.asarray(fitness(current, block)) == 0)))
        if log is not None:
            log(f"circle {np.round(best[1], 2).tolist()} at {np.round(best[2], 2).tolist()}: "
                f"{blocked[-1]}/{len(block)} blocked")
    return ObstacleLayout(tuple(circles), np.array(seeds).reshape(-1, 2), np.array(blocked),
                          len(block))


class BetterPaths(NamedTuple):
    """What ``free_paths_above`` found."""

    x: np.ndarray  # shape=(n_found, n_free): free paths with fitness above the threshold
    fitness: np.ndarray  # shape=(n_found,)
    best_x: np.ndarray  # shape=(n_free,): the fittest free path found, above or not
    best_fitness: float
    n_grid: int  # grid points whose obstacle-free fitness is above the threshold (all checked)
    n_restarts: int  # restarts of the default search (``jaxarm.solve``)


def free_paths_above(problem: Problem, threshold: float, low, high, *, step: float,
                     n_restarts: int = 0, seed: int = 0, chunk: int = 1 << 18) -> BetterPaths:
    """Free paths with fitness above ``threshold``: a grid and the default search look for them.

    The grid spans the box ``[low, high]`` every ``step``; only its points whose travelling
    distance alone would give a fitness above the threshold are checked for collision (the
    fitness can only drop from there). Then ``jaxarm.solve``'s default search (both of its
    methods, feasibility rules) runs ``n_restarts`` restarts per method, and every restart's
    best path that is free and above the threshold joins the grid's. Both use the problem's
    collision mode.

    Args:
      low, high: the grid's box, shape (n_free,).
      step: grid spacing.
      n_restarts: restarts per method of the default search (0: the grid only).
      seed: the search's seed.
      chunk: grid points per compiled call.

    Returns:
      ``BetterPaths``.
    """
    # the top layer, imported here: the rest of this module needs only the checks
    from jaxarm.search import solve

    low, high = (np.broadcast_to(np.asarray(v, np.float64), (problem.n_free,)) for v in (low, high))
    axes = [np.arange(lo, hi + step / 2, step) for lo, hi in zip(low, high)]
    shape = tuple(len(a) for a in axes)
    distance = jit(lambda x: path.simpson_distance(
        jnp.asarray(problem.start, x.dtype), jnp.asarray(problem.goal, x.dtype), x,
        problem.degree, problem.n_samples))
    found, n_grid = [np.zeros((0, problem.n_free))], 0
    total = int(np.prod(shape))
    for start in range(0, total, chunk):
        index = np.arange(start, start + chunk) % total  # one padded size: one program
        x = np.stack([a[i] for a, i in zip(axes, np.unravel_index(index, shape))], -1)
        above = (1.0 / np.asarray(distance(jnp.asarray(x, jnp.float32))) > threshold)
        above[min(chunk, total - start):] = False
        n_grid += int(above.sum())
        if above.any():
            x = x[above]
            found.append(x[np.asarray(fitness(problem, x)) > 0])
    if n_restarts:
        result = solve(problem, n_restarts=n_restarts, seed=seed, max_stages=1)
        free = result.restarts.feasible
        found.append(np.asarray(result.restarts.best_x, np.float64)[free])
    x = np.concatenate(found)
    values = np.asarray(fitness(problem, x), np.float64) if len(x) else np.zeros(0)
    keep = values > threshold
    best = int(np.argmax(values)) if len(x) else None
    return BetterPaths(x[keep], values[keep],
                       x[best] if best is not None else np.full(problem.n_free, np.nan),
                       float(values[best]) if best is not None else 0.0, n_grid,
                       n_restarts * len(DEFAULT_METHODS))


class BlockProof(NamedTuple):
    """What ``prove_blocked`` settled: every cell of the box either has fitness at most the
    threshold throughout, or collides throughout (at one sample, in one obstacle)."""

    threshold: float
    by_fitness: int  # cells whose every path has fitness <= threshold
    by_collision: int  # cells whose every path collides at a sample
    unresolved: np.ndarray  # shape=(n, n_free): centres of the cells settled neither way
    min_half_width: float  # half-width of the smallest cells examined
    levels: int  # subdivisions
    meets_box: bool  # some cell centre has an obstacle-free fitness above the threshold

    @property
    def proved(self) -> bool:
        """Every path above the threshold collides at a sample: nothing is left, and the
        better paths meet the box (convexity then puts all of them inside it)."""
        return len(self.unresolved) == 0 and self.meets_box


def _sample_bounds(problem: Problem):
    """Per sample of r: how far (cm per unit of every free parameter) a point of each link can
    move, and the travelling distance's Lipschitz constant (per unit, summed over parameters).

    A change of at most h in every free parameter changes joint k's angle at r by at most
    ``h S(r)``, ``S = sum_p |g_p(r)|`` over the basis (``path.basis_values``), so link m's
    absolute angle by ``m h S(r)`` and the far end of link j, hence every point of it, by
    ``h S(r) sum_{m <= j} m l_m``. Each joint's travelling distance (the sum over samples of
    ``w_i sqrt(1 + theta'(r_i)^2)``, 1-Lipschitz in ``theta'``) changes by at most
    ``h sum_i w_i S'(r_i)``.
    """
    r = np.linspace(0.0, 1.0, problem.n_samples)
    spread = np.abs(path.basis_values(problem.degree, r)[:, 1:]).sum(-1)  # (n_samples,)
    speed = np.abs(path.basis_values(problem.degree, r, order=1)[:, 1:]).sum(-1)
    lengths = np.asarray(problem.arm.lengths, np.float64)
    lever = np.cumsum(np.arange(1, len(lengths) + 1) * lengths)  # (n_links,): sum_{m<=j} m l_m
    moves = spread[:, None] * lever[None, :]  # (n_samples, n_links)
    lipschitz = problem.n_joints * float(np.sum(path.simpson_weights(problem.n_samples) * speed))
    return moves, lipschitz


def _depth_margin_fn(problem: Problem):
    """Jitted ``(x, h) -> margin``: over the samples and links, the largest amount by which a
    link's depth inside a circle (radius minus distance) exceeds how far the link can move in
    the cube of half-width h around x. Positive: every path of the cube collides. Float64."""
    moves, _ = _sample_bounds(problem)
    circles = np.asarray(problem.world.circles, np.float64).reshape(-1, 3)
    r = np.linspace(0.0, 1.0, problem.n_samples)

    def margin(x, h):
        theta = path.joint_angle_array(jnp.asarray(problem.start), jnp.asarray(problem.goal),
                                       x, path.basis_values(problem.degree, r))  # (n, s, joints)
        joints = joint_positions(jnp.asarray(problem.arm.lengths), theta)  # (n, s, j + 1, 2)
        a, b = joints[..., :-1, :], joints[..., 1:, :]  # (n, s, links, 2)
        centres = jnp.asarray(circles[:, :2]).reshape(1, 1, 1, -1, 2)
        radii = jnp.asarray(circles[:, 2]).reshape(1, 1, 1, -1)
        ab = (b - a)[..., None, :]  # (n, s, links, 1, 2)
        ap = centres - a[..., None, :]  # (n, s, links, circles, 2)
        t = jnp.clip(jnp.sum(ap * ab, -1) / jnp.maximum(jnp.sum(ab * ab, -1), 1e-30), 0, 1)
        gap = jnp.linalg.norm(ap - t[..., None] * ab, axis=-1)
        depth = jnp.max(radii - gap, axis=-1)  # (n, s, links)
        return jnp.max(depth - h[:, None, None] * jnp.asarray(moves)[None], axis=(-2, -1))

    return jit(margin)


# What the proof's float64 bounds must beat, for the float32 checks it speaks for: link
# positions there are off by about 1e-5 cm, the travelling distance by a few parts in 1e7.
COLLISION_SLACK = 1e-3  # cm
FITNESS_SLACK = 1e-5  # relative


def prove_blocked(problem: Problem, threshold: float, low, high, *, half_width: float = 8.0,
                  min_half_width: float = 1 / 64, max_cells: int = 1 << 22,
                  chunk: int = 1 << 12) -> BlockProof:
    """Show that no path in the box ``[low, high]`` is both free and above ``threshold``.

    Branch and bound over cubes of free parameters: a cube is settled when the travelling
    distance at its centre, less its Lipschitz bound over the cube, is still at least
    ``1 / threshold`` (every path in it has fitness <= threshold), or when at some sample of r
    a link of the centre's path lies deeper in an obstacle than any point of that link can
    move within the cube, by more than ``COLLISION_SLACK`` (every path in it collides at that
    sample, under the sampled check in float32 and under the certified one alike; bounds in
    ``_sample_bounds``). Other cubes are split in 2^n_free, down to ``min_half_width``; the
    centres of the cubes left are returned.
    Cubes on the box's boundary are settled only by fitness, so the box need not be known to
    hold every path above the threshold: if one reaches out, cubes stay unresolved. The
    travelling distance is convex in the free parameters (each theta' is affine in them and
    sqrt(1 + u^2) is convex), so the paths above the threshold form a convex set: when every
    boundary cube is settled by fitness and the set meets the box (some cube centre lies in it:
    ``BlockProof.meets_box``), it lies inside the box, and the proof covers every path. Float64
    throughout; worlds of circles only.

    Args:
      low, high: the box, shape (n_free,), a whole number of ``2 * half_width`` wide.
      half_width: half-width of the first cubes.
      max_cells: stop (unresolved cells returned) when a level would hold more cubes.
      chunk: cubes per compiled call.

    Returns:
      ``BlockProof``; ``proved`` when nothing is left.

    Raises:
      ValueError: the world holds boxes or polygons.
    """
    if problem.world.boxes or problem.world.polygons:
        raise ValueError(f"prove_blocked handles circles only; {problem.name!r} has "
                         f"{len(problem.world.boxes)} boxes and {len(problem.world.polygons)} "
                         "polygons")
    low, high = (np.broadcast_to(np.asarray(v, np.float64), (problem.n_free,)) for v in (low, high))
    with jax.enable_x64(True):
        _, lipschitz = _sample_bounds(problem)
        margin = _depth_margin_fn(problem)
        start = jnp.asarray(problem.start, jnp.float64)
        goal = jnp.asarray(problem.goal, jnp.float64)
        distance = jit(lambda x: path.simpson_distance(start, goal, x, problem.degree,
                                                       problem.n_samples))
        axes = [np.arange(lo + half_width, hi + half_width, 2 * half_width)
                for lo, hi in zip(low, high)]
        cells = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, problem.n_free)
        h, by_fitness, by_collision, levels, meets_box = half_width, 0, 0, 0, False
        corners = np.stack(np.meshgrid(*[[-1.0, 1.0]] * problem.n_free, indexing="ij"),
                           -1).reshape(-1, problem.n_free)
        while len(cells):
            keep = []
            for begin in range(0, len(cells), chunk):
                part = cells[begin:begin + chunk]
                padded = np.concatenate([part, np.repeat(part[:1], chunk - len(part), 0)])
                x = jnp.asarray(padded)
                centre_distance = np.asarray(distance(x))[:len(part)]
                meets_box |= bool(np.any(centre_distance < 1.0 / threshold))
                low_fit = centre_distance - lipschitz * h >= (1.0 + FITNESS_SLACK) / threshold
                hit = np.asarray(margin(x, jnp.full(chunk, h)))[:len(part)] > COLLISION_SLACK
                # on the box's boundary only fitness settles a cube: better paths reaching out
                # of the box leave cubes unresolved instead of going unseen
                hit &= ~np.any((part - h <= low + 1e-9) | (part + h >= high - 1e-9), axis=1)
                by_fitness += int(low_fit.sum())
                by_collision += int((hit & ~low_fit).sum())
                keep.append(part[~low_fit & ~hit])
            cells = np.concatenate(keep)
            if not len(cells) or h / 2 < min_half_width or len(cells) * len(corners) > max_cells:
                break
            h /= 2
            levels += 1
            cells = (cells[:, None, :] + h * corners[None]).reshape(-1, problem.n_free)
    return BlockProof(float(threshold), by_fitness, by_collision, cells, float(h), levels,
                      meets_box)


class BetterPathLayout(NamedTuple):
    """What ``block_better_paths`` built, round by round."""

    problem: Problem  # the problem with the obstacles added
    layout: ObstacleLayout  # the last round's obstacles
    block: np.ndarray  # shape=(n_block, n_free): every free path above the threshold found
    found: tuple  # per round: how many new free paths above the threshold the searches found


def block_better_paths(problem: Problem, keep_free, threshold: float, low, high, *,
                       gap: float = 0.05, step: float = 0.5, n_restarts: int = 64,
                       rounds: int = 6, max_obstacles: int = 6, log=None) -> BetterPathLayout:
    """Obstacles that block every free path with fitness above ``threshold`` and keep the
    ``keep_free`` motions ``gap`` clear: search, block, search again.

    Each round ``free_paths_above`` (the grid over ``[low, high]`` every ``step``, and
    ``n_restarts`` restarts per method of the default search, seeded by the round) looks for
    free paths above the threshold on the problem with the current obstacles; a finer grid
    (``step / 8``) around each of up to 16 of them adds their neighbours; then
    ``block_paths`` places the obstacles again, on the original problem, for every path
    found so far. It ends when a round finds none, when some found path cannot be blocked,
    or after ``rounds``.

    Args:
      problem: the problem to add obstacles to; its collision mode is the one searched
        (the paper's sampled check: a path that collides at a sample cannot be certified free).
      keep_free: free parameters that must stay free, shape (n_keep, n_free).
      low, high: the grid's box.
      gap, max_obstacles, log: as for ``block_paths``.

    Returns:
      ``BetterPathLayout``.
    """
    say = log or (lambda line: None)
    block = np.zeros((0, problem.n_free))
    layout = ObstacleLayout((), np.zeros((0, 2)), np.zeros(0, int), 0)
    current, found = problem, []
    for round_ in range(rounds):
        better = free_paths_above(current, threshold, low, high, step=step,
                                  n_restarts=n_restarts, seed=round_)
        new = [better.x]
        for x in better.x[np.argsort(-better.fitness)[:16]]:
            near = free_paths_above(current, threshold, x - step, x + step, step=step / 8)
            new.append(near.x)
        new = np.unique(np.concatenate(new), axis=0)
        found.append(len(new))
        say(f"round {round_ + 1}: {len(new)} free paths above {threshold} (best "
            f"{better.best_fitness:.5f} at {np.round(better.best_x, 3).tolist()})")
        if not len(new):
            break
        block = np.concatenate([block, new])
        layout = block_paths(problem, keep_free, block, gap=gap, max_obstacles=max_obstacles,
                             log=log)
        current = with_circles(problem, layout.circles)
        if not layout.blocked.size or layout.blocked[-1] < len(block):
            left = len(block) - (layout.blocked[-1] if layout.blocked.size else 0)
            say(f"  {left} paths left free: no circle within the gap blocks them")
            break
    return BetterPathLayout(current, layout, block, tuple(found))
