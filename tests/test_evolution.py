"""evosax strategies as study methods (``jaxarm.optim.evosax_adapter``)."""

import sys

import numpy as np
import pytest

import jaxarm
from jaxarm import cli, study
from jaxarm.optim import evosax_adapter, methods


def test_a_missing_evosax_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "evosax", None)  # import evosax now fails
    with pytest.raises(ValueError, match=r"evosax methods need evosax: pip install "
                                         r"'jaxarm\[bench\]'"):
        methods.parse_methods(["A", "evosax:CMA_ES"], "death")
    for argv in (["solve", "paper-case-2", "--method", "evosax:DE"],
                 ["study", "paper-case-2", "--methods", "A,evosax:DE"]):
        assert cli.main(argv) == 2  # one line, the same advice, from both commands
        assert "evosax methods need evosax: pip install" in capsys.readouterr().err


@pytest.fixture(scope="module")
def problem():
    pytest.importorskip("evosax")  # the tests below need the optional dependency
    return jaxarm.load_scenario("paper-case-2", collision="sampled")


def test_strategies_record_escape_and_fitness_like_the_pso(problem):
    result = study.escape_study(problem, ["evosax:CMA_ES", "evosax:DE:feasibility"], n_restarts=8,
                                n_particles=8, n_iters=15)
    for label in ("evosax:CMA_ES", "evosax:DE:feasibility"):
        outcome = result.method(label).outcome
        assert outcome.history.shape == (8, 16)
        fitness = np.asarray(jaxarm.fitness(problem, np.float32(outcome.best_x)))
        np.testing.assert_allclose(outcome.best_fitness, fitness, rtol=1e-6)
        for history, escape in zip(outcome.history, outcome.escape_iter):
            assert np.all(np.diff(history) >= 0)  # the best so far never gets worse
            if escape >= 0:
                assert np.all(history[:escape] == 0) and history[escape] > 0
            else:
                assert np.all(history == 0)
    assert result.method("evosax:DE:feasibility").outcome.escape_iter.max() >= 0  # some escape


def test_a_restart_does_not_depend_on_the_restarts_beside_it(problem):
    few = jaxarm.solve(problem, "evosax:CMA_ES", n_particles=8, n_iters=10, n_restarts=3,
                       seed=5, constraint="feasibility")
    many = jaxarm.solve(problem, "evosax:CMA_ES", n_particles=8, n_iters=10, n_restarts=11,
                        seed=5, constraint="feasibility")
    for name in ("best_x", "best_fitness", "escape_iter", "history"):
        np.testing.assert_array_equal(getattr(few.restarts, name),
                                      getattr(many.restarts, name)[:3])
    loaded = jaxarm.Result.from_json(few.to_json())
    assert loaded.config == evosax_adapter.StrategyConfig("CMA_ES") and loaded.method == "evosax:CMA_ES"


def test_bad_strategies_and_rules_are_refused(problem):
    with pytest.raises(ValueError, match=r"evosax has no strategy 'Nope'; it has .*CMA_ES"):
        methods.parse_methods(["evosax:Nope"], "death")
    with pytest.raises(ValueError, match=r"constraint of evosax:DE:epsilon must be one of "
                                         r"\('death', 'feasibility'\)"):
        methods.parse_methods(["evosax:DE:epsilon"], "death")
    with pytest.raises(ValueError, match="init_particles: evosax:CMA_ES starts from its own"):
        jaxarm.solve(problem, "evosax:CMA_ES", init_particles=[[0.0, 0.0, 0.0]])
