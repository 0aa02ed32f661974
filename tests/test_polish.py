"""Gradient polish (``jaxarm.refine``): never worse, never colliding, shapes."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import jaxarm
from jaxarm._compile.jit import jit  # compiles faster than jax.jit on CPU
from jaxarm.checks import collision
from jaxarm.model import path
from jaxarm.optim import refine as refine_lib
from jaxarm.paper import published


@pytest.fixture(scope="module")
def feasible_case2_paths(case2):
    """Paths free at the samples (case2 is sampled): the certified check refuses a few."""
    x = np.random.default_rng(7).uniform(-200, 200, (4000, 3))
    return x[np.asarray(jaxarm.violation(case2, x)) == 0]


@settings(max_examples=12)
@given(data=st.data(), mode=st.sampled_from(["sampled", "certified"]))
def test_refine_never_worsens_and_never_collides(feasible_case2_paths, data, mode):
    problem = jaxarm.load_scenario("paper-case-2", collision=mode)
    rows = data.draw(st.lists(st.integers(0, len(feasible_case2_paths) - 1), min_size=4,
                              max_size=4))
    x = feasible_case2_paths[rows]  # feasible when sampled; maybe not when certified
    feasible = np.asarray(jaxarm.violation(problem, x)) == 0
    polished = jaxarm.refine(problem, x, n_steps=20)
    assert np.all(polished.fitness >= polished.initial_fitness)
    assert not np.any(np.asarray(jaxarm.collides(problem, polished.x))[feasible])
    np.testing.assert_array_equal(polished.x[~feasible], x[~feasible].astype(np.float32))
    np.testing.assert_allclose(np.asarray(jaxarm.fitness(problem, polished.x)), polished.fitness,
                               rtol=1e-5)
    assert np.all(np.diff(polished.history, axis=-1) >= 0)


def test_refine_improves_a_deliberately_poor_path(case2):
    poor = published.CASE_2_TABLE_4[4]  # [181.07, -34.81, -147.86], fitness 0.0805
    polished = jaxarm.refine(case2, poor.a6)
    assert polished.fitness > poor.fitness + 0.01
    assert polished.n_accepted > 0 and polished.history.shape == (201,)


def test_refine_keeps_the_leading_shape_of_x(case2):
    poor = published.CASE_2_TABLE_4[4].a6
    x = np.stack([np.stack([poor, [0.0, 0.0, 0.0], poor])] * 2)  # (2, 3, n_free)
    polished = jaxarm.refine(case2, x, n_steps=20)  # the program of the first test, sampled
    assert polished.x.shape == (2, 3, 3) and polished.fitness.shape == (2, 3)
    assert polished.n_accepted.shape == (2, 3) and polished.history.shape == (2, 3, 21)
    np.testing.assert_array_equal(polished.x[:, 1], 0.0)  # the colliding row stays put
    single = jaxarm.refine(case2, poor, n_steps=20)
    np.testing.assert_array_equal(polished.x[1, 2], single.x)


def test_refine_leaves_a_colliding_path_alone(case2):
    polished = jaxarm.refine(case2, [0.0, 0.0, 0.0])  # blocked by the obstacle
    np.testing.assert_array_equal(polished.x, [0.0, 0.0, 0.0])
    assert polished.fitness == 0 and polished.n_accepted == 0


def test_refine_of_no_paths_is_empty(case2):
    """``solve(refine="all")`` and the report polish every feasible restart; there may be none."""
    polished = jaxarm.refine(case2, np.zeros((0, 3)), n_steps=5)
    assert polished.x.shape == (0, 3) and polished.fitness.shape == (0,)
    assert polished.history.shape == (0, 6) and polished.n_accepted.dtype == np.int32


def test_refine_shares_programs_and_rows_do_not_depend_on_their_neighbours(
        feasible_case2_paths, case2):
    rows = np.asarray(feasible_case2_paths)
    few = jaxarm.refine(case2, rows[:3], n_steps=20)
    before = refine_lib._compiled_refine.programs_made()
    many = jaxarm.refine(case2, np.concatenate([rows[:3], rows[:3], rows[:3] + 1.0]), n_steps=20)
    assert refine_lib._compiled_refine.programs_made() == before  # 3 and 9 rows: the same program
    np.testing.assert_array_equal(many.x[:3], few.x)
    np.testing.assert_array_equal(many.fitness[3:6], few.fitness)
    wide = jaxarm.refine(case2, rows[:40], n_steps=20)  # 64 rows
    np.testing.assert_array_equal(wide.x[:3], few.x)


def test_an_optimizer_with_a_global_norm_sees_one_row_at_a_time(feasible_case2_paths, case2):
    """refine's loop runs on the whole batch, but the optimizer is mapped over the rows: a
    norm clip must clip each path by its own gradient's norm, not the batch's."""
    clipped = optax.chain(optax.clip_by_global_norm(1e-3), optax.sgd(1.0))
    rows = np.asarray(feasible_case2_paths)[:3]
    together = jaxarm.refine(case2, rows, n_steps=5, optimizer=clipped)
    assert together.n_accepted.sum() > 0  # the steps moved something
    for i in range(3):
        alone = jaxarm.refine(case2, rows[i:i + 1], n_steps=5, optimizer=clipped)
        np.testing.assert_array_equal(alone.x[0], together.x[i])
        np.testing.assert_array_equal(alone.history[0], together.history[i])


def _surrogate_one_sample_at_a_time(problem, x, barrier_weight, margin, temperature):
    """The surrogate as folds over the samples (``path.run_fold``), as refine computed it
    before it took all samples at once."""
    arrays, spec = problem.arrays, problem.spec

    def add_barrier(total, sample):
        bounds = collision.posture_clearance_bound(arrays.lengths, arrays.world,
                                                   sample.derivatives[0], exact=False)
        return total + sum(temperature * jax.nn.softplus((margin + arrays.margin - c)
                                                         / temperature) for c in bounds)

    barrier = path.SampleFold(init=jnp.zeros(x.shape[:-1], x.dtype), step=add_barrier,
                              finish=lambda total: total / spec.n_samples, max_order=0)
    distance = path.simpson_distance(arrays.start, arrays.goal, x, spec.degree,
                                     spec.n_samples)
    return distance + barrier_weight * path.run_fold(barrier, arrays.start, arrays.goal, x,
                                                     spec.degree, spec.n_samples)


@pytest.mark.parametrize("name", ["paper-case-2", "death-trap"])
def test_the_surrogate_matches_a_fold_over_the_samples_and_its_gradient_autodiff(name):
    problem = jaxarm.load_scenario(name).replace(degree=6, n_samples=21)  # 2 free terms a joint
    x = np.random.default_rng(3).uniform(-60, 60, (16, problem.n_free)).astype(np.float32)
    weight, margin, temperature = 2.0, 1.0, 0.5  # none of them refine's defaults

    def at_once(z):
        return refine_lib.surrogate(problem.spec, problem.arrays, z, weight, margin, temperature)

    def folded(z):
        return _surrogate_one_sample_at_a_time(problem, z, weight, margin, temperature)

    np.testing.assert_allclose(jit(at_once)(x), jit(folded)(x), rtol=2e-5)
    # the chain rule written out against autodiff of the same value (checked above)
    autodiff = jit(jax.vmap(jax.grad(at_once)))(x)
    written_out = jit(lambda z: refine_lib.surrogate_gradient(
        problem.spec, problem.arrays, z, weight, margin, temperature))(x)
    np.testing.assert_allclose(written_out, autodiff, rtol=1e-4,
                               atol=1e-4 * float(np.abs(autodiff).max()))
