"""Figures (matplotlib, headless-safe: no pyplot, every function returns a ``Figure``).

- ``plot_motion``: the arm among obstacles at several instants, with the end-effector trace
  (paper Figs. 7a and 11);
- ``plot_joint_angles``: theta_k(r) (paper Fig. 7b);
- ``plot_convergence``: global-best fitness against iteration for many restarts, escapes
  marked (paper Fig. 12);
- ``plot_escape_rates`` and ``plot_escape_curves``: a study's escape rates with 95 % intervals
  and the fraction escaped by each iteration;
- ``animate``: a GIF of the motion.
"""

from __future__ import annotations

import numpy as np
from matplotlib import patches
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.figure import Figure

from jaxarm.arm import joint_positions
from jaxarm.problem import Problem, joint_path

OBSTACLE_STYLE = dict(facecolor="#c9c9c9", edgecolor="#555555", linewidth=1.0, zorder=1)


def _axes(ax, figsize=(5.5, 4.5)):
    if ax is not None:
        return ax.figure, ax
    figure = Figure(figsize=figsize, layout="constrained")
    return figure, figure.add_subplot()


def draw_world(ax, world) -> None:
    """Draw a ``World``'s obstacles on ``ax``."""
    for x, y, radius in world.circles:
        ax.add_patch(patches.Circle((x, y), radius, **OBSTACLE_STYLE))
    for vertices in world.polygon_vertices():
        ax.add_patch(patches.Polygon(vertices, closed=True, **OBSTACLE_STYLE))


def _positions(problem: Problem, x, r) -> np.ndarray:
    theta = joint_path(problem, np.asarray(x, dtype=np.float32), r)
    return np.asarray(joint_positions(problem.arm.lengths, theta))  # (n_r, n_joints + 1, 2)


def plot_motion(problem: Problem, x, n_postures: int = 9, ax=None, title: str | None = None):
    """The arm at ``n_postures`` instants of the path ``x`` (shape (n_free,)) among obstacles."""
    figure, ax = _axes(ax)
    draw_world(ax, problem.world)
    trace = _positions(problem, x, np.linspace(0.0, 1.0, 201))[:, -1]
    postures = _positions(problem, x, np.linspace(0.0, 1.0, n_postures))
    colors = [(0.15, 0.35 + 0.5 * t, 0.85 - 0.6 * t) for t in np.linspace(0, 1, n_postures)]
    for index, (posture, color) in enumerate(zip(postures, colors)):
        ends = index in (0, n_postures - 1)
        ax.plot(posture[:, 0], posture[:, 1], "-o", color=color, lw=2.2 if ends else 1.0,
                ms=3, alpha=1.0 if ends else 0.6, zorder=3)
    ax.plot(trace[:, 0], trace[:, 1], "--", color="#d62728", lw=1.2, label="end-effector",
            zorder=2)
    ax.plot(0, 0, "ks", ms=7, zorder=4)
    reach = problem.arm.reach
    ax.set_xlim(-reach * 0.6, reach * 1.05)
    ax.set_ylim(-reach * 0.6, reach * 1.05)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title or f"{problem.name}: motion")
    return figure


def plot_joint_angles(problem: Problem, x, ax=None, title: str | None = None):
    """theta_k(r) for every joint of the path ``x``."""
    figure, ax = _axes(ax, (5.5, 3.5))
    r = np.linspace(0.0, 1.0, 201)
    theta = np.asarray(joint_path(problem, np.asarray(x, dtype=np.float32), r))
    for k in range(problem.n_joints):
        ax.plot(r, theta[:, k], label=f"θ{k + 1}")
    ax.set_xlabel("r = t / T")
    ax.set_ylabel("joint angle (rad)")
    ax.legend(fontsize=8)
    ax.set_title(title or f"{problem.name}: joint angles")
    return figure


def plot_convergence(history, escape_iter, ax=None, title: str = "Escape and evolution"):
    """Global-best fitness per iteration for many restarts; escapes marked, failures in grey.

    Args:
      history: shape (n_restarts, n_iters + 1); escape_iter: shape (n_restarts,).
    """
    figure, ax = _axes(ax, (6.0, 3.8))
    history, escape_iter = np.atleast_2d(history), np.atleast_1d(escape_iter)
    iterations = np.arange(history.shape[1])
    for curve, escape in zip(history, escape_iter):
        ax.plot(iterations, curve, color="#1f77b4" if escape >= 0 else "#bbbbbb", lw=0.8,
                alpha=0.7)
    escaped = escape_iter >= 0
    ax.scatter(escape_iter[escaped], history[escaped, escape_iter[escaped]], s=14,
               color="#d62728", zorder=3, label=f"escape ({escaped.sum()}/{len(escape_iter)})")
    ax.set_xlabel("iteration")
    ax.set_ylabel("best fitness")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(title)
    return figure


def plot_escape_rates(study, ax=None, title: str | None = None):
    """Escape rate of each method of a ``Study`` with its 95 % Wilson interval."""
    figure, ax = _axes(ax, (5.5, 3.5))
    labels = [m.variant.label for m in study.methods]
    rates = np.array([m.escape_rate() for m in study.methods])
    intervals = np.array([m.escape_interval() for m in study.methods])
    errors = np.abs(intervals.T - rates)
    colors = ["#2ca02c" if m.variant.constraint == "feasibility" else "#1f77b4"
              for m in study.methods]
    ax.bar(labels, rates, yerr=errors, capsize=4, color=colors)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("escape rate")
    ax.set_title(title or f"{study.problem_name}: escape within {study.n_iters} iterations "
                          f"({study.methods[0].n_seeds} seeds)")
    return figure


def plot_escape_curves(study, ax=None, title: str | None = None):
    """Fraction of seeds escaped by each iteration, one curve per method."""
    figure, ax = _axes(ax, (5.5, 3.5))
    for method in study.methods:
        ax.step(np.arange(study.n_iters + 1), method.escape_curve(), where="post",
                label=method.variant.label)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("iteration")
    ax.set_ylabel("fraction escaped")
    ax.legend(fontsize=8)
    ax.set_title(title or f"{study.problem_name}: escape by iteration")
    return figure


def animate(problem: Problem, x, path, n_frames: int = 60, fps: int = 20) -> None:
    """Write a GIF of the motion ``x`` to ``path``."""
    figure, ax = _axes(None)
    draw_world(ax, problem.world)
    frames = _positions(problem, x, np.linspace(0.0, 1.0, n_frames))
    reach = problem.arm.reach
    ax.set_xlim(-reach * 0.6, reach * 1.05)
    ax.set_ylim(-reach * 0.6, reach * 1.05)
    ax.set_aspect("equal")
    (arm,) = ax.plot([], [], "-o", color="#1f3f99", lw=2.5, ms=4)
    (trace,) = ax.plot([], [], "--", color="#d62728", lw=1.0)

    def update(index):
        arm.set_data(frames[index, :, 0], frames[index, :, 1])
        trace.set_data(frames[: index + 1, -1, 0], frames[: index + 1, -1, 1])
        return arm, trace

    FuncAnimation(figure, update, frames=n_frames, blit=False).save(
        str(path), writer=PillowWriter(fps=fps)
    )
