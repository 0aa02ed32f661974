"""Figures (``jaxarm.plot``)."""

import jaxarm
from jaxarm import plot, study

SMALL = dict(n_particles=8, n_iters=12)


def test_plots_produce_non_empty_pngs(tmp_path, case2):
    result = jaxarm.solve(case2, "A", n_restarts=4, **SMALL)
    escape = study.escape_study(case2, ["A", "A:feasibility"], n_seeds=4, **SMALL)
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
