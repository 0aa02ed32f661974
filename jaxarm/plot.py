"""Figures (matplotlib, headless-safe: no pyplot, every function returns a ``Figure``).

- ``plot_motion``: the arm among obstacles at several instants, with the end-effector trace
  (paper Figs. 7a and 11), and where a colliding path collides;
- ``plot_joint_angles``: theta_k(r) (paper Fig. 7b);
- ``plot_clearance``: each link's distance to the nearest obstacle against r, with the margin;
- ``plot_convergence``: global-best fitness against iteration for many restarts, escapes
  marked (paper Fig. 12);
- ``plot_escape_rates`` and ``plot_escape_curves``: a study's escape rates with 95 % intervals
  and the fraction escaped by each iteration;
- ``plot_evolving_gains``: what escaped runs gain after their escape, ours against the paper's;
- ``plot_feasible_map``: a 2-D slice of the free-coefficient space, coloured by fitness;
- ``plot_profiles``: a trajectory's position, velocity, acceleration (and torque) against time,
  with the limits as dashed lines;
- ``animate``: a GIF of the motion.
"""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib import patches
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.figure import Figure

from jaxarm._compile.jit import jit
from jaxarm._validate import positive_int
from jaxarm.checks.evaluate import deepest_contact, fitness
from jaxarm.checks.witness import clearance_along
from jaxarm.model.arm import joint_positions
from jaxarm.model.path_functions import joint_path
from jaxarm.model.problem import Problem, check_problem

OBSTACLE_STYLE = dict(facecolor="#c9c9c9", edgecolor="#555555", linewidth=1.0, zorder=1)


def _axes(ax, figsize=(5.5, 4.5)):
    if ax is not None:
        return ax.figure, ax
    figure = Figure(figsize=figsize, layout="constrained")
    return figure, figure.add_subplot()


def _fit_title(ax, text: str) -> None:
    """``ax.set_title(text)``, broken into lines where the figure is too narrow for it: the
    figure is laid out (no pixels drawn) and the title wrapped shorter until all of it lies
    inside the figure, at most four times."""
    ax.set_title(text)
    root = ax.figure.figure  # the whole figure, also for an axes in a subfigure
    inside = ax.figure.bbox.padded(-2.0)
    width = len(text)
    for _ in range(4):
        root.draw_without_rendering()
        extent = ax.title.get_window_extent()
        if extent.x0 >= inside.x0 and extent.x1 <= inside.x1:
            return
        width = max(12, int(width * min(inside.width / extent.width, 0.9)))
        ax.set_title(textwrap.fill(text, width))


def draw_world(ax, world) -> None:
    """Draw a ``World``'s obstacles on ``ax``."""
    for index in range(world.n_obstacles):
        ax.add_patch(_obstacle_patch(world, index, **OBSTACLE_STYLE))


def _one_path(problem: Problem, x) -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    if x.shape != (problem.n_free,):
        batch = "; pick one row of a batch" if x.ndim > 1 and x.shape[-1] == problem.n_free else ""
        raise ValueError(f"x must be one path of shape ({problem.n_free},), got shape "
                         f"{x.shape}{batch}")
    return x


def _coefficient_name(problem: Problem, index: int) -> str:
    """Free coefficient ``index``'s name as the paper writes it: a61 is joint 1's a6 (x holds
    them by power, then joint); a6,11 past nine joints."""
    power, joint = divmod(index, problem.n_joints)
    return f"a{6 + power}{',' if problem.n_joints > 9 else ''}{joint + 1}"


# Compiled: op by op, a solve's figures compiled many tiny programs in every new process, most
# of the time they took. ``joint_path`` is compiled too.
_compiled_positions = jit(joint_positions)


def _positions(problem: Problem, x, r) -> np.ndarray:
    theta = joint_path(problem, _one_path(problem, x), r)
    return np.asarray(_compiled_positions(problem.arrays.lengths, theta))  # (n_r, n_joints + 1, 2)


def _show_workspace(ax, problem: Problem) -> None:
    """Equal axes that hold everything the arm can reach and every obstacle, labelled in cm."""
    reach = problem.arm.reach
    low, high = np.array([-reach, -reach]), np.array([reach, reach])
    world = problem.world
    for x, y, radius in world.circles:
        low, high = np.minimum(low, [x - radius, y - radius]), np.maximum(high, [x + radius,
                                                                                 y + radius])
    for vertices in world.polygon_vertices():
        low, high = np.minimum(low, vertices.min(axis=0)), np.maximum(high, vertices.max(axis=0))
    pad = 0.05 * float(np.max(high - low))
    ax.set_xlim(low[0] - pad, high[0] + pad)
    ax.set_ylim(low[1] - pad, high[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")


def plot_motion(problem: Problem, x, n_postures: int = 9, ax=None, title: str | None = None):
    """The arm at ``n_postures`` instants of the path ``x`` (shape (n_free,)) among obstacles.

    A path that comes inside an obstacle (or its margin) at the drawn instants is drawn with
    where: crosses on the end-effector's trace at those instants, and the arm at its deepest
    contact (``evaluate.deepest_contact``, as ``Result.summary`` names it) and the obstacle
    it hits, in red.
    """
    check_problem(problem)
    figure, ax = _axes(ax)
    draw_world(ax, problem.world)
    r = np.linspace(0.0, 1.0, 201)
    trace = _positions(problem, x, r)[:, -1]
    postures = _positions(problem, x, np.linspace(0.0, 1.0, n_postures))
    colors = [(0.15, 0.35 + 0.5 * t, 0.85 - 0.6 * t) for t in np.linspace(0, 1, n_postures)]
    for index, (posture, color) in enumerate(zip(postures, colors)):
        ends = index in (0, n_postures - 1)
        label = {0: "start", n_postures - 1: "goal", 1: "in between"}.get(index)
        ax.plot(posture[:, 0], posture[:, 1], "-o", color=color, lw=2.2 if ends else 1.0,
                ms=3, alpha=1.0 if ends else 0.6, zorder=3, label=label)
    ax.plot(trace[:, 0], trace[:, 1], "--", color="#d62728", lw=1.2, label="end-effector",
            zorder=2)
    _mark_collision(ax, problem, x, r, trace)
    ax.plot(0, 0, "ks", ms=7, zorder=4, label="base")
    _show_workspace(ax, problem)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or f"{problem.name}: motion")
    return figure


def _mark_collision(ax, problem: Problem, x, r, trace) -> None:
    """Where the path collides (``plot_motion``): crosses at the instants ``r`` where exact
    distances put a link inside an obstacle or its margin, and, if the problem's check finds
    the path colliding, its witness. A path clear at every instant costs no check."""
    distance = clearance_along(problem, _one_path(problem, x), r)[0]
    inside = distance.min(axis=1) < problem.margin
    if not inside.any():
        return
    ax.plot(trace[inside, 0], trace[inside, 1], "x", color="#d62728", ms=5, zorder=4,
            label="in collision")
    witness = deepest_contact(problem, _one_path(problem, x))
    if not witness.found:
        return
    posture = _positions(problem, x, np.array([float(witness.r)]))[0]
    ax.plot(posture[:, 0], posture[:, 1], "-", color="#d62728", lw=2.6, zorder=5,
            label=f"deepest contact, r = {float(witness.r):.3g}")
    if int(witness.obstacle) >= 0:
        ax.add_patch(_obstacle_patch(problem.world, int(witness.obstacle), facecolor="none",
                                     edgecolor="#d62728", linewidth=2.2, zorder=5))
    else:  # two links: both drawn thick
        for link in (int(witness.link), int(witness.other_link)):
            ax.plot(posture[link:link + 2, 0], posture[link:link + 2, 1], "-", color="#8b0000",
                    lw=4.0, zorder=6)


def _obstacle_patch(world, index: int, **style):
    """Obstacle ``index`` (``World``'s order) as a matplotlib patch."""
    if index < len(world.circles):
        x, y, radius = world.circles[index]
        return patches.Circle((x, y), radius, **style)
    vertices = world.polygon_vertices()[index - len(world.circles)]
    if len(vertices) == 2:  # a segment: a wall of zero thickness, drawn as a thick line
        style = style | {"linewidth": max(style.get("linewidth", 1.0), 2.5)}
    return patches.Polygon(vertices, closed=True, **style)


def plot_clearance(problem: Problem, x, n_points: int = 401, ax=None,
                   title: str | None = None):
    """Each link's exact distance to its nearest obstacle along the path ``x`` (shape
    (n_free,)) against r, with the margin (and 0) dashed: where a line dips below, that link
    collides; the deepest contact (``evaluate.deepest_contact``) is marked."""
    check_problem(problem)
    n_points = positive_int("n_points", n_points, minimum=2)
    figure, ax = _axes(ax, (5.5, 3.5))
    r = np.linspace(0.0, 1.0, n_points)
    distance = clearance_along(problem, _one_path(problem, x), r)[0]
    for link in range(problem.n_joints):
        ax.plot(r, distance[:, link], lw=1.2, label=f"link {link + 1}")
    ax.axhline(0.0, color="black", lw=0.8)
    if problem.margin:
        ax.axhline(problem.margin, color="#d62728", ls="--", lw=1.0,
                   label=f"margin {problem.margin:g} cm")
    witness = deepest_contact(problem, _one_path(problem, x))
    if witness.found:
        ax.plot(float(witness.r), float(witness.distance), "x", color="#d62728", ms=9, mew=2,
                label=f"witness: link {int(witness.link) + 1}", zorder=4)
    finite = distance[np.isfinite(distance)]
    if finite.size:  # the nearest few tens of cm: far obstacles do not squeeze the plot
        top = max(problem.margin, 0.0) + max(5.0, float(np.percentile(finite, 50)))
        ax.set_ylim(min(float(finite.min()), 0.0) - 0.5, top)
    ax.set_xlabel("r = t / T")
    ax.set_ylabel("distance to nearest obstacle (cm)")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(title or f"{problem.name}: clearance by link")
    return figure


def plot_joint_angles(problem: Problem, x, ax=None, title: str | None = None):
    """theta_k(r) for every joint of the path ``x``."""
    check_problem(problem)
    figure, ax = _axes(ax, (5.5, 3.5))
    r = np.linspace(0.0, 1.0, 201)
    theta = np.asarray(joint_path(problem, _one_path(problem, x), r))
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
    """Escape rate of each method of a ``Study`` with its 95 % Wilson interval, coloured by
    constraint rule."""
    labels = [m.variant.label for m in study.methods]
    rates = np.array([m.escape_rate() for m in study.methods])
    intervals = np.array([m.escape_interval() for m in study.methods])
    errors = np.abs(intervals.T - rates)
    figure, ax = _axes(ax, (max(5.5, 0.9 * len(labels) + 1.5), 3.8))
    palette = {"death": ("#1f77b4", "death penalty"), "feasibility": ("#2ca02c",
                                                                       "feasibility rules"),
               "epsilon": ("#ff7f0e", "epsilon-constrained"), "penalty": ("#9467bd",
                                                                           "adaptive penalty")}
    rules = [m.variant.constraint for m in study.methods]
    ax.bar(labels, rates, yerr=errors, capsize=4, color=[palette[r][0] for r in rules])
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("escape rate (95 % interval)")
    ax.tick_params(axis="x", labelrotation=30)
    for label in ax.get_xticklabels():
        label.set_horizontalalignment("right")
    ax.legend(handles=[patches.Patch(color=palette[r][0], label=palette[r][1])
                       for r in dict.fromkeys(rules)], fontsize=8, loc="upper left",
              bbox_to_anchor=(1.0, 1.0))  # beside the axes: bars reach 1.0 on either side
    _fit_title(ax, title or f"{study.problem_name}: escape within {study.n_iters} iterations "
                            f"({study.methods[0].n_restarts} seeds, {study.collision} check)")
    return figure


def plot_evolving_gains(ours: dict, paper: dict, ax=None, title: str | None = None):
    """What escaped runs gain between their escape and the last iteration: per preset, our
    seeds' gains as a box (whiskers at the 5th and 95th percentiles) and the paper's runs as
    dots.

    Args:
      ours: ``{preset label: study.EvolvingRuns}``: our escaped seeds.
      paper: the paper's runs, the same labels in the same order.
      ax: the axes to draw on (None: a new figure).
      title: the figure's title (None: a default).
    """
    labels = list(ours)
    figure, ax = _axes(ax, (max(5.0, 1.2 * len(labels) + 2.0), 3.8))
    positions = np.arange(len(labels))
    boxes = ax.boxplot([ours[label].gain for label in labels], positions=positions, widths=0.5,
                       whis=(5, 95), showfliers=False)
    for i, label in enumerate(labels):
        gains = paper[label].gain
        ax.plot(np.full(len(gains), positions[i] + 0.32), gains, "o", color="#d62728",
                markersize=5, label="paper: escaped runs" if i == 0 else None)
    ax.set_xticks(positions, labels)
    ax.set_ylabel("fitness gained after the escape")
    ax.axhline(0.0, color="0.7", linewidth=0.8)
    handles, names = ax.get_legend_handles_labels()  # boxplot's label= needs matplotlib 3.9
    ax.legend([boxes["boxes"][0], *handles], ["ours: escaped seeds", *names], fontsize=8,
              loc="best")
    _fit_title(ax, title or "Fitness gained between escape and the last iteration")
    return figure


def plot_escape_curves(study, ax=None, title: str | None = None):
    """Fraction of seeds escaped by each iteration, one curve per method, each with its
    pointwise 95 % Wilson band."""
    from jaxarm.stats import wilson_interval

    figure, ax = _axes(ax, (5.5, 3.5))
    iterations = np.arange(study.n_iters + 1)
    for method in study.methods:
        curve = method.escape_curve()
        counts = np.rint(curve * method.n_restarts).astype(int)
        band = np.array([wilson_interval(int(k), method.n_restarts) for k in counts])
        (line,) = ax.step(iterations, curve, where="post", label=method.variant.label)
        ax.fill_between(iterations, band[:, 0], band[:, 1], step="post", alpha=0.2, lw=0,
                        color=line.get_color())
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("iteration")
    ax.set_ylabel("fraction escaped (95 % band)")
    ax.legend(fontsize=8)
    _fit_title(ax, title or f"{study.problem_name}: escape by iteration "
                            f"({study.methods[0].n_restarts} seeds, {study.collision} check)")
    return figure


def plot_feasible_map(problem: Problem, x, dims=(0, 1), *, resolution: int = 121, bounds=None,
                      best=None, ax=None, title: str | None = None,
                      point_label: str = "slice through this path"):
    """Fitness on the plane through ``x`` spanned by free coefficients ``dims``; paths that
    collide (fitness 0) in grey. Answers "what does the feasible set look like?" (paper 11.3).

    Args:
      x: the slice's base point, shape (n_free,) (marked with a cross).
      dims: the two coefficient indices varied (the others stay at x's values).
      resolution: grid points per axis (>= 2).
      bounds: ``((low_i, high_i), (low_j, high_j))``; default: the problem's init range.
      best: optional second point to mark (a swarm's best, say), shape (n_free,).
      point_label: the legend's name for ``x``.
    """
    check_problem(problem)
    x = _one_path(problem, x).astype(np.float64)
    i, j = dims
    if len(set(dims)) != 2 or not all(0 <= d < problem.n_free for d in dims):
        raise ValueError(f"dims must be two different indices in [0, {problem.n_free}), "
                         f"got {dims!r}")
    resolution = positive_int("resolution", resolution, minimum=2)
    if bounds is None:
        low, high = problem.bounds()
        bounds = ((low[i], high[i]), (low[j], high[j]))
    (low_i, high_i), (low_j, high_j) = np.asarray(bounds, dtype=np.float64)
    if not (low_i < high_i and low_j < high_j):
        raise ValueError(f"bounds must be ((low, high), (low, high)) with low < high, "
                         f"got {bounds!r}")
    u, v = np.linspace(low_i, high_i, resolution), np.linspace(low_j, high_j, resolution)
    grid = np.repeat(x[None, None], resolution, axis=0).repeat(resolution, axis=1)
    grid[..., i], grid[..., j] = u[None, :], v[:, None]
    values = np.asarray(fitness(problem, grid))  # (rows: v, columns: u)
    figure, ax = _axes(ax, (5.5, 4.5))
    ax.set_facecolor("#bdbdbd")  # colliding paths: masked, so the background shows
    image = ax.imshow(np.ma.masked_equal(values, 0.0), origin="lower", aspect="auto",
                      extent=(low_i, high_i, low_j, high_j), cmap="viridis")
    figure.colorbar(image, ax=ax, label="fitness (grey: collides)")
    ax.plot(x[i], x[j], "x", color="#d62728", ms=9, mew=2, label=point_label)
    if best is not None:
        best = _one_path(problem, best)
        ax.plot(best[i], best[j], "*", color="white", mec="black", ms=12, label="best")
    ax.set_xlabel(f"{_coefficient_name(problem, i)} (free coefficient {i})")
    ax.set_ylabel(f"{_coefficient_name(problem, j)} (free coefficient {j})")
    ax.legend(fontsize=8, loc="upper right")
    free = float(np.mean(values > 0))
    ax.set_title(title or f"{problem.name}: slice ({i}, {j}), {free:.1%} of it free")
    return figure


def plot_profiles(trajectory, *, max_velocity=None, max_acceleration=None, max_torque=None,
                  n_points: int = 401):
    """Position, velocity, acceleration and, when the arm's masses are known, torque of every
    joint against time; joint limits (``problem.joint_limits``) and the limits given as dashed
    lines in each joint's colour.

    Args:
      trajectory: a ``jaxarm.Trajectory``.
      max_velocity: a scalar or one value per joint, as for ``jaxarm.min_duration``.
      max_acceleration: the same way.
      max_torque: the same way.
      n_points: times drawn.

    Returns:
      A ``Figure`` with one panel per quantity.
    """
    from jaxarm.trajectory import per_joint_limit

    n_points = positive_int("n_points", n_points, minimum=2)
    problem = trajectory.problem
    t = np.linspace(0.0, trajectory.duration, n_points)
    state = trajectory.at(t)
    panels = [("position", "rad", state.position, problem.joint_limits),
              ("velocity", "rad/s", state.velocity,
               per_joint_limit("max_velocity", max_velocity, problem.n_joints)),
              ("acceleration", "rad/s²", state.acceleration,
               per_joint_limit("max_acceleration", max_acceleration, problem.n_joints))]
    if problem.arm.masses is not None:
        panels.append(("torque", "N·m", trajectory.torques(t),
                       per_joint_limit("max_torque", max_torque, problem.n_joints)))
    figure = Figure(figsize=(6.0, 2.0 * len(panels)), layout="constrained")
    axes = figure.subplots(len(panels), 1, sharex=True)
    for ax, (name, unit, values, limits) in zip(axes, panels):
        for joint in range(problem.n_joints):
            line, = ax.plot(t, values[:, joint], label=f"joint {joint + 1}")
            if limits is None:
                continue
            bounds = limits[joint] if name == "position" else (-limits[joint], limits[joint])
            for bound in bounds:
                ax.axhline(bound, color=line.get_color(), linestyle="--", linewidth=0.9)
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[0].set_title(f"{problem.name}: T = {trajectory.duration:.4g} s")
    axes[-1].set_xlabel("t (s)")
    return figure


def animate(problem: Problem, x, path, n_frames: int = 60, fps: int = 20) -> None:
    """Write a GIF of the motion ``x`` (shape (n_free,)) to ``path`` (a .gif file): the arm at
    ``n_frames`` equally spaced r, shown at ``fps`` frames per second."""
    check_problem(problem)
    if str(path).lower()[-4:] != ".gif":
        raise ValueError(f"path must end in .gif, got {str(path)!r}")
    positive_int("n_frames", n_frames, minimum=2)
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 100:
        raise ValueError(f"fps must be a number in (0, 100], got {fps!r}")
    figure, ax = _axes(None)
    draw_world(ax, problem.world)
    r = np.linspace(0.0, 1.0, n_frames)
    frames = _positions(problem, x, r)
    _show_workspace(ax, problem)
    ax.set_title(f"{problem.name}: motion")
    ax.plot(0, 0, "ks", ms=7, zorder=4)
    (arm,) = ax.plot([], [], "-o", color="#1f3f99", lw=2.5, ms=4, label="arm")
    (trace,) = ax.plot([], [], "--", color="#d62728", lw=1.0, label="end-effector")
    ax.legend(loc="upper right", fontsize=8)
    clock = ax.text(0.02, 0.96, "", transform=ax.transAxes, va="top", fontsize=9)

    def update(index):
        arm.set_data(frames[index, :, 0], frames[index, :, 1])
        trace.set_data(frames[: index + 1, -1, 0], frames[: index + 1, -1, 1])
        clock.set_text(f"r = t / T = {r[index]:.2f}")
        return arm, trace, clock

    FuncAnimation(figure, update, frames=n_frames, blit=False).save(
        str(path), writer=PillowWriter(fps=fps)
    )
