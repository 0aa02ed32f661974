"""Recovering the paper's scenarios from its published numbers.

The paper's figures of the case-1 postures and of every obstacle did not survive, but its
tables did (``jaxarm.paper.published``). Two facts make them usable:

- Fitness (1 / travelling distance) depends only on the joint displacement ``goal - start``
  and on a6, never on the obstacles; so the 17 published case-1 fitness values pin the start and
  goal postures once the end-effector positions are fixed (``fit_postures``).
- A published coefficient set is a verdict: collision-free (fitness > 0) or colliding (0). An
  obstacle layout is consistent with the paper when it keeps every feasible set free and blocks
  the infeasible ones, and the death-penalty PSO then escapes about as often as the paper's did.
  ``circle_candidates`` lists the largest circles that keep the feasible sets clear and
  ``greedy_circles`` picks a few of them that block the most of the initial range (and every
  set that must be blocked); ``label_agreement`` scores any problem against the verdicts.

Everything runs on jaxarm's own batched kernels; see ``benchmarks/reconstruct_scenarios.py`` for
the runs that produced the shipped scenario files; ``benchmarks/blocking.py`` adds the obstacles
that block case 1's paths better than the paper's runs found.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm._compile.jit import jit
from jaxarm.checks.evaluate import fitness
from jaxarm.model import path
from jaxarm.model.arm import Arm, joint_positions
from jaxarm.model.poses import inverse_kinematics
from jaxarm.model.path_functions import joint_path
from jaxarm.model.problem import Problem
from jaxarm.paper.published import PublishedSet, a6_array


class PostureFit(NamedTuple):
    """Start and goal postures fitted to published fitness values (``fit_postures``)."""

    start: np.ndarray  # shape=(3,), rad
    goal: np.ndarray  # shape=(3,), rad
    start_phi: float  # end-effector orientation at the start, rad
    goal_phi: float
    start_elbow: int  # sign of joint 2 at the start
    goal_elbow: int
    fitness: np.ndarray  # shape=(n_sets,), fitness of each published set with these postures
    relative_error: np.ndarray  # shape=(n_sets,), |ours - published| / published


def _postures(arm: Arm, point, phis: np.ndarray, elbow: int) -> np.ndarray:
    """Inverse kinematics over orientations; NaN rows where the pose is out of reach.

    Returns:
      Array of shape (len(phis), 3).
    """
    rows = []
    for phi in phis:
        try:
            rows.append(inverse_kinematics(arm, point[0], point[1], float(phi), elbow))
        except ValueError:
            rows.append(np.full(3, np.nan))
    return np.stack(rows)


def _worst_errors_fn(x: np.ndarray, published: np.ndarray, n_samples: int):
    """Jitted ``(starts, goals) -> worst relative fitness error`` over broadcast pairs."""
    x = jnp.asarray(x, jnp.float32)

    def worst(start, goal):
        distance = path.simpson_distance(start, goal, x, 6, n_samples)
        return jnp.max(jnp.abs(1.0 / distance - published) / published)

    def pairs(starts, goals):  # (n_starts, n_goals), one start at a time to bound memory
        goals = goals.astype(jnp.float32)
        return jax.lax.map(lambda start: jax.vmap(worst, (None, 0))(start, goals),
                           starts.astype(jnp.float32))

    return jit(pairs)


def fit_postures(arm: Arm, end_points, sets: Sequence[PublishedSet], *, n_samples: int = 101,
                 grid: int = 360, starts: int = 8, rounds: int = 40,
                 shrink: float = 0.5) -> PostureFit:
    """Start and goal postures whose paths reproduce the published fitness values best.

    The end-effector is held at ``end_points`` exactly (3-link inverse kinematics); the unknowns
    are the two orientations and the two elbow signs. The worst relative error over the sets is
    minimised by a grid over both orientations for each elbow pair, then, from each of the
    ``starts`` best grid points, a pattern search that shrinks a 9 x 9 grid around its best pair
    ``rounds`` times by ``shrink``; the best result wins. Degree 6 (the paper's).

    Args:
      arm: a 3-link arm.
      end_points: ((x, y) at the start, (x, y) at the goal), cm.
      sets: published sets with positive fitness.
      n_samples: Simpson points of r for the travelling distance.
      grid: orientations per full turn in the first grid.
      starts: grid points each refined by a pattern search.
      rounds, shrink: pattern-search refinements and the grid's shrink factor per round.

    Returns:
      ``PostureFit``.
    """
    sets = [s for s in sets if s.feasible]
    if not sets:
        raise ValueError("sets must contain at least one published set with fitness > 0")
    x = a6_array(sets)
    published = np.array([s.fitness for s in sets], np.float64)
    worst = _worst_errors_fn(x, published, n_samples)
    (start_xy, goal_xy) = end_points

    def errors(elbows, phis_start, phis_goal):
        starts = _postures(arm, start_xy, phis_start, elbows[0])
        goals = _postures(arm, goal_xy, phis_goal, elbows[1])
        values = np.asarray(worst(jnp.asarray(starts), jnp.asarray(goals)), np.float64)
        return np.where(np.isfinite(values), values, np.inf)  # (n_phis_start, n_phis_goal)

    phis = np.linspace(-np.pi, np.pi, grid, endpoint=False)
    seeds = []  # (error, phi_start, phi_goal, elbows)
    for elbows in itertools.product((1, -1), repeat=2):
        table = errors(elbows, phis, phis)
        for flat in np.argsort(table, axis=None)[:starts]:
            i, j = np.unravel_index(flat, table.shape)
            seeds.append((table[i, j], phis[i], phis[j], elbows))
    seeds = sorted(seeds, key=lambda seed: seed[0])[:starts]
    offsets = np.linspace(-1.0, 1.0, 9)
    best = None
    for error, phi_start, phi_goal, elbows in seeds:
        span = 2 * np.pi / grid
        for _ in range(rounds):
            table = errors(elbows, phi_start + span * offsets, phi_goal + span * offsets)
            i, j = np.unravel_index(np.argmin(table), table.shape)
            error, phi_start, phi_goal = table[i, j], phi_start + span * offsets[i], \
                phi_goal + span * offsets[j]
            span *= shrink
        if best is None or error < best[0]:
            best = (error, phi_start, phi_goal, elbows)
    _, phi_start, phi_goal, elbows = best
    start = inverse_kinematics(arm, *start_xy, phi_start, elbows[0])
    goal = inverse_kinematics(arm, *goal_xy, phi_goal, elbows[1])
    ours = 1.0 / np.asarray(path.simpson_distance(jnp.asarray(start), jnp.asarray(goal),
                                                  jnp.asarray(x), 6, n_samples), np.float64)
    return PostureFit(start, goal, float(phi_start), float(phi_goal), elbows[0], elbows[1],
                      ours, np.abs(ours - published) / published)


class Verdict(NamedTuple):
    """One published set judged on a problem (``label_agreement``)."""

    published: PublishedSet
    fitness: float  # ours, on the problem
    agrees: bool  # our verdict (fitness > 0) equals the paper's


def label_agreement(problem: Problem, sets: Sequence[PublishedSet]) -> list[Verdict]:
    """Whether ``problem`` gives each published set the paper's verdict (free or colliding)."""
    ours = np.asarray(fitness(problem, a6_array(sets)), np.float64)
    return [Verdict(s, float(f), bool((f > 0) == s.feasible)) for s, f in zip(sets, ours)]


def sweep_distances(problem: Problem, x, points, n_points: int, chunk: int = 256) -> np.ndarray:
    """Distance from each point to the arm (every link) along each path, at ``n_points`` of r.

    Args:
      x: free parameters, shape (n_paths, n_free).
      points: shape (n_points_xy, 2), cm.
      n_points: equally spaced times of r at which the links are measured.
      chunk: paths per compiled call (bounds memory).

    Returns:
      Array of shape (n_paths, n_points_xy): the smallest distance over the sampled motion.
    """
    x = np.asarray(x, np.float32)
    points = jnp.asarray(points, jnp.float32)
    r = np.linspace(0.0, 1.0, n_points)
    lengths = jnp.asarray(problem.arm.lengths, jnp.float32)

    @jit
    def nearest(x_chunk):
        theta = joint_path(problem, x_chunk, r)  # (paths, n_points, joints)
        joints = joint_positions(lengths, theta)  # (paths, n_points, joints + 1, 2)
        a, b = joints[..., :-1, :], joints[..., 1:, :]  # link ends
        a = a.reshape(a.shape[0], -1, 2)
        ab = b.reshape(a.shape) - a

        def to_point(p):
            p = p.reshape(1, 1, 2)  # one point, against every path's links
            t = jnp.clip(jnp.sum((p - a) * ab, -1) / jnp.sum(ab * ab, -1), 0.0, 1.0)
            return jnp.min(jnp.linalg.norm(a + t[..., None] * ab - p, axis=-1), axis=-1)

        return jax.lax.map(to_point, points).T

    n_paths = len(x)
    chunk = min(chunk, n_paths)
    padded = np.concatenate([x, np.zeros((-n_paths % chunk, x.shape[1]), np.float32)])
    rows = [np.asarray(nearest(padded[i:i + chunk])) for i in range(0, len(padded), chunk)]
    return np.concatenate(rows)[:n_paths]


def circle_candidates(problem: Problem, keep_free, *, spacing: float = 2.0, gap: float = 0.5,
                      min_radius: float = 2.0, n_points: int = 401) -> np.ndarray:
    """The largest circles on a grid of centres that keep the ``keep_free`` paths clear.

    Centres lie every ``spacing`` cm over the arm's reach; each radius is the centre's distance
    to the free paths' sweep (at ``n_points`` times, denser than the paper's check) minus
    ``gap``; centres whose radius falls below ``min_radius`` are dropped, as are circles that
    swallow the base.

    Returns:
      Array of shape (n_candidates, 3): centre x, centre y, radius.
    """
    reach = problem.arm.reach
    ticks = np.arange(-reach, reach + 1e-9, spacing)
    centres = np.stack(np.meshgrid(ticks, ticks), -1).reshape(-1, 2)
    centres = centres[np.hypot(*centres.T) < reach]
    clearance = sweep_distances(problem, np.asarray(keep_free, np.float64).reshape(
        -1, problem.n_free), centres, n_points).min(axis=0)
    radius = clearance - gap
    keep = (radius >= min_radius) & (np.hypot(*centres.T) > radius)
    return np.column_stack([centres[keep], radius[keep]])


class CircleLayout(NamedTuple):
    """Circles chosen by ``greedy_circles`` and what each step achieved."""

    circles: np.ndarray  # shape=(n_circles, 3): centre x, centre y, radius
    free_fraction: np.ndarray  # shape=(n_circles,), share of random paths still free after each
    blocked: np.ndarray  # shape=(n_circles,), int: how many ``block`` paths are blocked after each
    n_paths: int  # random paths drawn from the initial range


def greedy_circles(problem: Problem, candidates, n_circles: int, *, block=(),
                   n_paths: int = 6000, seed: int = 0) -> CircleLayout:
    """Pick circles that block the most of the initial range, and every ``block`` path first.

    ``n_paths`` random coefficient sets are drawn uniformly from the problem's initial range; a
    circle blocks a path when some link comes within its radius at one of the problem's
    ``n_samples`` points of r (the paper's sampled check). Each step takes the candidate that
    blocks the most ``block`` paths not yet blocked, ties broken by the most random paths.

    Args:
      candidates: shape (n_candidates, 3), e.g. from ``circle_candidates``.
      block: free parameters that must collide, shape (n_block, n_free).

    Returns:
      ``CircleLayout``.
    """
    candidates = np.asarray(candidates, np.float64)
    low, high = (np.asarray(b, np.float64) for b in problem.bounds())
    paths = np.random.default_rng(seed).uniform(low, high, (n_paths, problem.n_free))
    block = np.asarray(block, np.float64).reshape(-1, problem.n_free)
    covers = sweep_distances(problem, np.concatenate([block, paths]), candidates[:, :2],
                             problem.n_samples) < candidates[:, 2]
    must, random_paths = covers[: len(block)], covers[len(block):]
    must_open, open_paths = np.ones(len(block), bool), np.ones(n_paths, bool)
    chosen, free_fraction, blocked = [], [], []
    for _ in range(n_circles):
        gain = ((must & must_open[:, None]).sum(0) * (n_paths + 1)
                + (random_paths & open_paths[:, None]).sum(0))
        best = int(np.argmax(gain))
        chosen.append(best)
        must_open &= ~must[:, best]
        open_paths &= ~random_paths[:, best]
        free_fraction.append(open_paths.mean())
        blocked.append(int((~must_open).sum()))
    return CircleLayout(candidates[chosen], np.array(free_fraction), np.array(blocked), n_paths)
