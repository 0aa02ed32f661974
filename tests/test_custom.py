"""Your own optimiser (``jaxarm.optim.custom``) in solve and escape_study: written to the public
protocol with nothing but jax and jaxarm's public names, recorded as the PSO is, reproducible,
and refused with one line where it breaks the protocol."""

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import pytest

import jaxarm
from benchmark_modules import load

OnePlusLambdaES = load("own_optimiser").OnePlusLambdaES  # written to the protocol alone
SMALL = dict(n_iters=6, n_restarts=8)


@pytest.fixture(scope="module")
def problem(case2):
    return case2.replace(collision="sampled")


@pytest.fixture(scope="module")
def study(problem):
    return jaxarm.escape_study(problem, [OnePlusLambdaES(), "A:feasibility"], **SMALL)


def test_an_optimiser_runs_in_a_study_beside_pso_as_pso_runs(problem, study):
    es, pso = study.methods
    assert es.variant.label == "(1+8)-ES" and study.n_particles == 8
    assert es.summary()["velocity_rule"] == "own optimiser"
    assert es.outcome.history.shape == (8, SMALL["n_iters"] + 1)
    # the kept path is what the problem's check says of it
    feasible = es.outcome.feasible
    assert feasible.any()
    np.testing.assert_array_equal(es.outcome.best_fitness[feasible],
                                  jaxarm.fitness(problem, es.outcome.best_x[feasible]))
    assert np.all(np.diff(es.outcome.history, axis=1) >= 0)  # the best so far never worsens
    comparison = study.compare("(1+8)-ES", "A:feasibility")
    assert comparison.only_a + comparison.only_b <= 8
    assert "(1+8)-ES" in study.table()


def test_its_restarts_repeat_bit_for_bit_whatever_the_batch(problem, study):
    again = jaxarm.escape_study(problem, OnePlusLambdaES(), n_iters=SMALL["n_iters"],
                                n_restarts=17)  # run as 24, against 8
    first = study.methods[0].outcome
    for field, a, b in zip(first._fields, first, again.methods[0].outcome):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b)[:8], err_msg=field)


def test_solve_takes_it_and_records_its_label(problem):
    result = jaxarm.solve(problem, OnePlusLambdaES(), constraint="feasibility", **SMALL)
    assert result.method == "(1+8)-ES" and result.restarts.best_x.shape == (8, 3)
    assert "own optimiser" in result.summary()
    again = jaxarm.Result.from_json(result.to_json())
    assert again.config.optimizer == "(1+8)-ES"
    with pytest.raises(ValueError, match=r"keeps no code: pass the optimiser object"):
        jaxarm.solve(problem, again.config)


@pytest.mark.parametrize("change, message", [
    (dict(label="a:b"), r"label must be a name without ':' or ','"),
    (dict(population=1), r"population of '\(1\+8\)-ES' must be an int >= 2, got 1"),
    (dict(tell=None), r"tell of '\(1\+8\)-ES' must be a function"),
    (dict(ask=lambda self, key, state: (jnp.zeros((3, 3)), state)),
     r"ask of '\(1\+8\)-ES' must return x of shape \(8, 3\) \(population, n_free\), "
     r"got \(3, 3\)"),
    (dict(ask=lambda self, key, state: jnp.zeros((8, 3))),
     r"ask of '\(1\+8\)-ES' must return \(x, state\), got an array of shape \(8, 3\)"),
])
def test_a_broken_optimiser_is_refused_with_one_line(problem, change, message):
    broken = type("Broken", (OnePlusLambdaES,), change)()
    with pytest.raises(ValueError, match=message):
        jaxarm.solve(problem, broken, n_iters=2)


@pytest.mark.parametrize("constraint", ["death", "feasibility"])
def test_a_path_measured_nan_is_never_kept_as_the_best(problem, constraint):
    """An optimiser asking a non-finite path each iteration: NaN fitness and violation rank
    last, never as a free path of fitness 0 (before, every restart that did not escape kept
    the NaN path as its best)."""
    class AsksNaN(OnePlusLambdaES):
        def ask(self, key, state):
            x, state = super().ask(key, state)
            return x.at[0].set(jnp.nan), state

    outcome = jaxarm.solve(problem, AsksNaN(), constraint=constraint, **SMALL).restarts
    assert np.all(np.isfinite(np.asarray(outcome.best_x)))
    assert not np.any(np.isnan(np.asarray(outcome.best_violation)))


class FrozenES(NamedTuple):
    """The same ES as a NamedTuple: equal objects share one compiled program."""

    label: str = "(1+8)-ES"
    population: int = 8
    init = OnePlusLambdaES.init
    ask = OnePlusLambdaES.ask
    tell = OnePlusLambdaES.tell


def test_under_the_certified_check_and_as_a_namedtuple(problem):
    certified = problem.replace(collision="certified")
    result = jaxarm.solve(certified, FrozenES(), constraint="feasibility", **SMALL)
    assert result.method == "(1+8)-ES"
    if result.feasible:
        assert result.certified and jaxarm.certify(certified, result.best_x).free
    made = jaxarm.optim.restarts.compiled_search.programs_made()
    again = jaxarm.solve(certified, FrozenES(), constraint="feasibility", **SMALL)
    assert jaxarm.optim.restarts.compiled_search.programs_made() == made  # an equal object
    np.testing.assert_array_equal(again.restarts.best_x, result.restarts.best_x)


def test_a_state_that_changes_its_type_is_named(problem):
    class Drifting(OnePlusLambdaES):
        def tell(self, state, x, evaluation):
            return dict(super().tell(state, x, evaluation), sigma=jnp.int32(1))

    with pytest.raises(ValueError, match=r"tell of '\(1\+8\)-ES' changed state\['sigma'\] "
                                         r"from float32\[\] to int32\[\]"):
        jaxarm.solve(problem, Drifting(), n_iters=2)


def test_what_does_not_fit_the_call_is_refused(problem):
    es = OnePlusLambdaES()
    with pytest.raises(ValueError, match=r"asks 8 paths per iteration but n_particles=20"):
        jaxarm.escape_study(problem, [es], n_particles=20, n_restarts=2, n_iters=2)
    with pytest.raises(ValueError, match=r"must be one of \('death', 'feasibility'\)"):
        jaxarm.solve(problem, es, constraint="epsilon")
    with pytest.raises(ValueError, match=r"init_particles: \(1\+8\)-ES starts from its own"):
        jaxarm.solve(problem, es, init_particles=np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"an optimiser with label, population, init, ask, "):
        jaxarm.solve(problem, object())
    with pytest.raises(ValueError, match=r"OnePlusLambdaES is a class: pass an instance"):
        jaxarm.solve(problem, OnePlusLambdaES)
    with pytest.raises(ValueError, match=r"method Half \(an object\) lacks label, population: "
                                         r"an optimiser needs"):
        jaxarm.solve(problem, type("Half", (), {"init": 0, "ask": 0, "tell": 0})())
    with pytest.raises(ValueError, match=r"must not be a built-in method's name, got 'A'"):
        jaxarm.solve(problem, type("Named", (OnePlusLambdaES,), {"label": "A"})())
