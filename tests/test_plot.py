"""Figures (``jaxarm.plot``)."""

import types

import numpy as np
import pytest
from sizes import SMALL

import jaxarm
from jaxarm import plot, study
from jaxarm.model.arm import joint_positions


def test_plots_produce_non_empty_pngs(tmp_path, case2):
    result = jaxarm.solve(case2, "A", n_restarts=4, **SMALL)
    escape = study.escape_study(case2, ["A", "A:feasibility"], n_restarts=4, **SMALL)
    figures = {
        "motion": plot.plot_motion(case2, result.best_x),
        "joints": plot.plot_joint_angles(case2, result.best_x),
        "convergence": plot.plot_convergence(result.restarts.history, result.restarts.escape_iter),
        "rates": plot.plot_escape_rates(escape),
        "curves": plot.plot_escape_curves(escape),
    }
    for name, figure in figures.items():
        path = tmp_path / f"{name}.png"
        figure.savefig(path)
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000
    gif = tmp_path / "motion.gif"
    plot.animate(case2, result.best_x, gif, n_frames=5)
    assert gif.read_bytes()[:6] == b"GIF89a"


def test_figures_explain_themselves(tmp_path, case2):
    x = np.array([66.7388, -28.1028, -9.8855], np.float32)
    ax = plot.plot_motion(case2, x).axes[0]
    reach = case2.arm.reach
    (x_low, x_high), (y_low, y_high) = ax.get_xlim(), ax.get_ylim()
    assert x_low <= -reach and x_high >= reach and y_low <= -reach and y_high >= reach
    legend = [text.get_text() for text in ax.get_legend().get_texts()]
    assert {"start", "goal", "end-effector", "base"} <= set(legend)
    assert ax.get_xlabel() == "x (cm)" and ax.get_ylabel() == "y (cm)"
    escape = study.escape_study(case2, ["A", "A:feasibility", "B", "C:feasibility", "A:epsilon",
                                        "A:penalty"], n_restarts=3, **SMALL)
    ax = plot.plot_escape_rates(escape).axes[0]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "death penalty", "feasibility rules", "epsilon-constrained", "adaptive penalty"]
    title = " ".join(ax.get_title().split())  # wrapped to the figure's width
    assert "3 seeds" in title and f"{case2.collision} check" in title
    assert all(label.get_rotation() == 30 for label in ax.get_xticklabels())
    ax = plot.plot_escape_curves(escape).axes[0]
    assert len(ax.collections) == 6  # one 95 % band per method
    band = ax.collections[0].get_paths()[0].vertices[:, 1]
    title = " ".join(ax.get_title().split())
    assert band.min() >= 0 and band.max() <= 1 and "3 seeds" in title
    assert f"{case2.collision} check" in title


def test_the_drawn_arm_is_the_path_the_api_computes(case2):
    """The figures compute the path in compiled programs; the lines they draw are the
    joint angles and positions of ``jaxarm.joint_path`` and ``joint_positions``."""
    x = np.array([66.7388, -28.1028, -9.8855], np.float32)
    r = np.linspace(0.0, 1.0, 5)
    theta = np.asarray(jaxarm.joint_path(case2, x, r))
    positions = np.asarray(joint_positions(case2.arm.lengths, theta))
    lines = plot.plot_motion(case2, x, n_postures=5).axes[0].get_lines()
    for line, expected in zip(lines[:5], positions):
        np.testing.assert_allclose(line.get_xydata(), expected, atol=1e-4)
    curves = plot.plot_joint_angles(case2, x).axes[0].get_lines()
    dense = np.asarray(jaxarm.joint_path(case2, x, np.linspace(0.0, 1.0, 201)))
    for k, curve in enumerate(curves):
        np.testing.assert_allclose(curve.get_ydata(), dense[:, k], rtol=1e-6, atol=1e-6)


def test_plots_reject_what_they_cannot_draw(tmp_path, case2):
    batch = np.zeros((2, 3))
    for function in (plot.plot_motion, plot.plot_joint_angles):
        with pytest.raises(ValueError, match=r"x must be one path of shape \(3,\), got shape "
                                             r"\(2, 3\)"):
            function(case2, batch)
    x = np.zeros(3)
    for kwargs, message in ((dict(n_frames=0), "n_frames must be >= 2, got 0"),
                            (dict(fps=0), r"fps must be a number in \(0, 100\], got 0"),
                            (dict(path=tmp_path / "a.png"), "path must end in .gif")):
        arguments = dict(path=tmp_path / "a.gif") | kwargs
        with pytest.raises(ValueError, match=message):
            plot.animate(case2, x, **arguments)
    assert not (tmp_path / "a.gif").exists()


def test_feasible_map_colours_free_paths_and_greys_colliding_ones(case2):
    x = np.array([66.7388, -28.1028, -9.8855])
    figure = plot.plot_feasible_map(case2, x, dims=(0, 2), resolution=9, best=x)
    ax = figure.axes[0]
    image = ax.get_images()[0].get_array()  # masked where the path collides
    low, high = case2.bounds()
    u, v = np.linspace(low[0], high[0], 9), np.linspace(low[2], high[2], 9)
    grid = np.stack(np.broadcast_arrays(u[None, :], x[1], v[:, None]), axis=-1)
    expected = np.asarray(jaxarm.fitness(case2, grid))
    np.testing.assert_array_equal(image.mask, expected == 0)
    np.testing.assert_allclose(image.filled(0.0), expected)
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"slice through this path",
                                                               "best"}
    assert f"{np.mean(expected > 0):.1%} of it free" in ax.get_title()
    # the paper's names: a61 is joint 1's a6, a63 joint 3's
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("a61 (free coefficient 0)",
                                                  "a63 (free coefficient 2)")
    deeper = case2.replace(degree=8)  # x by power, then joint: index 4 is joint 2's a7
    figure = plot.plot_feasible_map(deeper, np.zeros(9), dims=(4, 8), resolution=2)
    assert (figure.axes[0].get_xlabel(), figure.axes[0].get_ylabel()) == (
        "a72 (free coefficient 4)", "a83 (free coefficient 8)")
    ten_joints = types.SimpleNamespace(n_joints=10)  # past nine joints, a comma between
    assert [plot._coefficient_name(ten_joints, i) for i in (0, 9, 10, 25)] == [
        "a6,1", "a6,10", "a7,1", "a8,6"]
    with pytest.raises(ValueError, match=r"x must be one path of shape \(3,\), got shape "
                                         r"\(2,\)$"):
        plot.plot_motion(case2, [1.0, 2.0])
    with pytest.raises(ValueError, match=r"got shape \(2, 3\); pick one row of a batch"):
        plot.plot_motion(case2, np.zeros((2, 3)))
    for kwargs, message in ((dict(dims=(1, 1)), "dims must be two different indices"),
                            (dict(dims=(0, 3)), "dims must be two different indices"),
                            (dict(resolution=1), "resolution must be >= 2"),
                            (dict(bounds=((1, 0), (0, 1))), "bounds must be")):
        with pytest.raises(ValueError, match=message):
            plot.plot_feasible_map(case2, x, **kwargs)


def _synthetic_study(labels, n_restarts=100, n_iters=100):
    """A study of the given method labels with made-up outcomes (no search runs)."""
    from jaxarm.optim.methods import parse_method
    from jaxarm.optim.restarts import RestartOutcome

    rng = np.random.default_rng(0)
    methods = []
    for label in labels:
        escape = np.where(rng.random(n_restarts) < 0.6, rng.integers(0, n_iters, n_restarts), -1)
        history = np.where(np.arange(n_iters + 1) >= np.where(escape < 0, n_iters + 1,
                                                              escape)[:, None], 0.2, 0.0)
        outcome = RestartOutcome(np.zeros((n_restarts, 3)), history[:, -1],
                                 np.where(escape < 0, 1.0, 0.0), escape.astype(np.int32),
                                 np.zeros((n_restarts, 3)), history)
        methods.append(study.MethodStudy(parse_method(label), np.arange(n_restarts), outcome,
                                         1.0, 0.5))
    return study.Study("death-trap", "certified", 20, n_iters, 0, tuple(methods))


SIX_METHODS = ["A:feasibility", "B:feasibility", "A-ring[inertia_end=0.4]:feasibility", "C",
               "A-global-ring:epsilon", "B:penalty"]


@pytest.mark.parametrize("n_methods", range(1, 7))
def test_every_text_of_a_study_figure_lies_inside_it(n_methods):
    """Titles, labels, tick labels and legends of the study figures, for one to six methods."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    escape = _synthetic_study(SIX_METHODS[:n_methods])
    for figure in (plot.plot_escape_rates(escape), plot.plot_escape_curves(escape)):
        FigureCanvasAgg(figure)
        renderer = figure.canvas.get_renderer()
        figure.draw(renderer)
        box = figure.bbox
        titles = [ax.title.get_text() for ax in figure.axes]
        assert any("escape" in title for title in titles)  # the title is drawn
        for ax in figure.axes:  # what is drawn: title, labels, tick labels, legend
            drawn = ax.get_tightbbox(renderer)
            assert (drawn.x0 >= box.x0 - 0.5 and drawn.x1 <= box.x1 + 0.5
                    and drawn.y0 >= box.y0 - 0.5 and drawn.y1 <= box.y1 + 0.5), (
                f"{titles}: drawn over {drawn}, the figure is {box}")


def test_a_study_figure_in_a_subfigure_fits_its_title_there():
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 3), layout="constrained")
    left, _ = figure.subfigures(1, 2)
    ax = left.add_subplot()
    plot.plot_escape_rates(_synthetic_study(SIX_METHODS[:3]), ax=ax)
    figure.draw_without_rendering()
    title, box = ax.title.get_window_extent(), left.bbox
    assert title.x0 >= box.x0 - 0.5 and title.x1 <= box.x1 + 0.5
