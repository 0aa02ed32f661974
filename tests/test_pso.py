"""PSO engine and solve: velocity rules, presets, determinism, ties, NaN, compile-once."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxarm
from jaxarm import pso
from jaxarm.solve import compiled_search
from jaxarm.study import wilson_interval

LOW, HIGH = jnp.full(2, -1.0), jnp.full(2, 1.0)


def sphere(x):
    """Maximise -|x - 0.3|^2; feasible where x[0] > 0.5."""
    fitness = -jnp.sum((x - 0.3) ** 2, axis=-1)
    return pso.Scored(score=fitness, fitness=fitness, feasible=x[:, 0] > 0.5)


def test_presets_are_the_papers_table_2():
    a, b, c = (pso.PRESETS[name] for name in "ABC")
    assert (a.velocity_rule, a.cognitive_coeff, a.social_coeff) == ("inertia", 1.5, 1.5)
    assert (b.velocity_rule, b.cognitive_coeff, b.social_coeff) == ("inertia", 0.5, 0.5)
    assert (a.inertia_start, a.inertia_end) == (b.inertia_start, b.inertia_end) == (1.0, 0.0)
    assert (c.velocity_rule, c.cognitive_coeff, c.social_coeff) == ("constriction", 3.0, 2.0)
    assert round(c.constriction, 4) == 0.3820
    assert a.constriction == b.constriction == 1.0


@pytest.mark.parametrize(
    "config",
    [
        pso.PSOConfig("original", 2.0, 2.0, init_velocity=0.3),
        pso.PSOConfig("inertia", 1.5, 1.5, 1.0, 0.0, init_velocity=0.3),
        pso.PSOConfig("inertia", 1.5, 1.5, 0.9, 0.4, init_velocity=0.3, velocity_clamp=0.05),
        pso.PSOConfig("constriction", 3.0, 2.0, 1.0, 1.0, init_velocity=0.3, beta="particle"),
    ],
)
def test_one_step_matches_a_hand_computation(config):
    numbers, structure = config.numbers(), config.structure()
    state, _ = pso.init(jax.random.key(1), sphere, numbers, structure, LOW, HIGH, 5)
    # Make personal bests differ from positions so every term of the rule matters.
    state = state._replace(best_position=state.best_position * 0.5, global_index=jnp.int32(3))
    key = jax.random.key(7)
    new, _ = pso.step(key, state, sphere, numbers, structure, LOW, HIGH, n_iters=10)

    beta_key, _ = jax.random.split(key)
    shape = (5, 2) if config.beta == "dimension" else (5, 1)
    beta1, beta2 = np.asarray(jax.random.uniform(beta_key, (2,) + shape))
    x, v = np.asarray(state.position), np.asarray(state.velocity)
    p = np.asarray(state.best_position)
    g = p[3]
    if config.velocity_rule == "original":
        chi, omega = 1.0, 1.0
    else:
        chi = config.constriction
        omega = config.inertia_start + (config.inertia_end - config.inertia_start) * 1 / 10
    expected_v = chi * (omega * v + config.cognitive_coeff * beta1 * (p - x)
                        + config.social_coeff * beta2 * (g - x))
    if config.velocity_clamp is not None:
        expected_v = np.clip(expected_v, -0.1, 0.1)  # 0.05 of the range 2
    np.testing.assert_allclose(np.asarray(new.velocity), expected_v, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(new.position), x + expected_v, rtol=1e-5, atol=1e-6)
    assert int(new.iteration) == 1


def test_personal_and_global_bests_follow_strict_improvement():
    config = pso.PRESETS["A"]
    state, _ = pso.init(jax.random.key(2), sphere, config.numbers(), config.structure(),
                        LOW, HIGH, 8)
    for t in range(5):
        previous = state
        state, info = pso.step(jax.random.key(t), state, sphere, config.numbers(),
                               config.structure(), LOW, HIGH, 5)
        score = np.asarray(sphere(state.position).score)
        improved = score > np.asarray(previous.best_score)
        np.testing.assert_array_equal(np.asarray(state.best_score),
                                      np.where(improved, score, previous.best_score))
        assert int(state.global_index) == int(np.argmax(np.asarray(state.best_score)))
        assert float(info.global_score) == float(np.max(np.asarray(state.best_score)))


def all_infeasible(x):
    zero = jnp.zeros(x.shape[0])
    return pso.Scored(score=zero, fitness=zero, feasible=zero > 0)


def test_all_infeasible_death_penalty_keeps_particle_zero_as_global_best():
    """Paper-faithful MATLAB `max` tie-breaking: the documented evosax PR #109 behaviour."""
    config = pso.PRESETS["A"]
    state, _ = pso.init(jax.random.key(3), all_infeasible, config.numbers(), config.structure(),
                        LOW, HIGH, 6)
    start = np.asarray(state.position)
    for t in range(4):
        state, _ = pso.step(jax.random.key(t), state, all_infeasible, config.numbers(),
                            config.structure(), LOW, HIGH, 4)
        assert int(state.global_index) == 0
        np.testing.assert_array_equal(np.asarray(state.best_position), start)
    assert int(state.escape_iter) == -1


def test_random_tie_break_spreads_the_global_best():
    config = pso.PSOConfig(tie_break="random")
    chosen = set()
    for seed in range(20):
        state, _ = pso.init(jax.random.key(seed), all_infeasible, config.numbers(),
                            config.structure(), LOW, HIGH, 6)
        chosen.add(int(state.global_index))
    assert len(chosen) >= 4


def test_nan_and_inf_never_become_a_best():
    def poisoned(x):
        fitness = jnp.where(x[:, 0] > 0, jnp.nan, -jnp.sum(x**2, axis=-1))
        fitness = fitness.at[1].set(jnp.inf)
        return pso.Scored(score=fitness, fitness=fitness, feasible=jnp.isfinite(fitness))

    config = pso.PSOConfig("original", 2.0, 2.0, init_velocity=5.0)  # diverges quickly
    state, _ = pso.init(jax.random.key(4), poisoned, config.numbers(), config.structure(),
                        LOW, HIGH, 10)
    for t in range(30):
        state, info = pso.step(jax.random.key(t), state, poisoned, config.numbers(),
                               config.structure(), LOW, HIGH, 30)
        assert np.all(np.isfinite(np.asarray(state.best_position)))
        assert np.isfinite(float(info.global_score))
        best = int(state.global_index)
        assert float(state.best_score[best]) > -np.inf


def test_escape_iteration_is_the_first_with_a_feasible_particle():
    config = pso.PRESETS["A"]
    low, high = jnp.full(2, -1.0), jnp.full(2, 0.0)  # the initial swarm is all infeasible
    state, _ = pso.init(jax.random.key(5), sphere, config.numbers(), config.structure(),
                        low, high, 10)
    assert int(state.escape_iter) == -1
    first = None
    for t in range(1, 40):
        state, info = pso.step(jax.random.key(t), state, sphere, config.numbers(),
                               config.structure(), low, high, 40)
        if first is None and int(info.n_feasible) > 0:
            first = t
    assert first is not None and int(state.escape_iter) == first


def test_bad_configs_name_the_field():
    with pytest.raises(ValueError, match=r"velocity_rule must be one of .* got 'fast'"):
        pso.resolve(pso.PSOConfig(velocity_rule="fast"))
    with pytest.raises(ValueError, match=r"constriction needs .* > 4, got 1.0 \+ 2.0"):
        pso.resolve(pso.PSOConfig("constriction", 1.0, 2.0))
    with pytest.raises(ValueError, match=r"cognitive_coeff must be a finite number >= 0"):
        pso.resolve(pso.PSOConfig(cognitive_coeff=float("nan")))
    with pytest.raises(ValueError, match=r"method must be one of \['A', 'B', 'C'\]"):
        pso.resolve("D")


# --- solve ---------------------------------------------------------------------------------

SMALL = dict(n_particles=8, n_iters=12)


def test_same_seed_gives_bit_identical_results(case2):
    first = jaxarm.solve(case2, "A", n_restarts=4, seed=11, **SMALL)
    second = jaxarm.solve(case2, "A", n_restarts=4, seed=11, **SMALL)
    np.testing.assert_array_equal(first.restart_best_x, second.restart_best_x)
    np.testing.assert_array_equal(first.restart_history, second.restart_history)
    other = jaxarm.solve(case2, "A", n_restarts=4, seed=12, **SMALL)
    assert not np.array_equal(first.restart_best_x, other.restart_best_x)


@pytest.mark.parametrize("n_restarts", [3, 8])
def test_restart_results_do_not_depend_on_how_many_run(case2, n_restarts):
    few = jaxarm.solve(case2, "B", n_restarts=n_restarts, seed=3, constraint="feasibility",
                       **SMALL)
    sixteen = jaxarm.solve(case2, "B", n_restarts=16, seed=3, constraint="feasibility", **SMALL)
    np.testing.assert_array_equal(few.restart_best_x, sixteen.restart_best_x[:n_restarts])
    np.testing.assert_array_equal(few.restart_escape_iter,
                                  sixteen.restart_escape_iter[:n_restarts])
    np.testing.assert_array_equal(few.restart_history, sixteen.restart_history[:n_restarts])


@pytest.mark.slow
def test_jit_equals_no_jit_on_one_restart(case2):
    case2 = case2.replace(n_samples=11)  # eager scans run sample by sample in Python
    config = pso.PRESETS["C"]
    args = (case2.spec, case2.arrays, config.numbers(), config.structure(),
            *(jnp.asarray(b, jnp.float32) for b in case2.bounds()), jnp.int32(0),
            jnp.zeros(1, jnp.int32), None)
    sizes = dict(n_particles=4, n_iters=2, constraint="feasibility")
    jitted = compiled_search(*args, **sizes)
    with jax.disable_jit():
        eager = jaxarm.solve.__globals__["search"](*args, **sizes)
    for a, b in zip(jitted, eager):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-4)


def test_a_second_problem_with_the_same_sizes_does_not_recompile(case2, case3):
    jaxarm.solve(case2, "A", n_restarts=2, **SMALL)
    before = compiled_search._cache_size()
    jaxarm.solve(case3, "B", n_restarts=2, seed=5, **SMALL)  # new data, new preset, new seed
    jaxarm.solve(case2.replace(start=[5.7, 1.2, 0.7]), "C", n_restarts=2, **SMALL)
    assert compiled_search._cache_size() == before


def test_init_particles_seed_the_swarm(case2):
    known = [66.7388, -28.1028, -9.8855]  # paper Table 6, fitness 0.1946
    result = jaxarm.solve(case2, "A", n_restarts=3, init_particles=[known], **SMALL)
    assert np.all(result.restart_escape_iter == 0)
    assert np.all(result.restart_best_fitness >= 0.1946)
    assert np.all(result.restart_history[:, 0] >= 0.1946)
    with pytest.raises(ValueError, match=r"init_particles must have shape \(n_given <= 8, 3\)"):
        jaxarm.solve(case2, init_particles=np.zeros((2, 4)), **SMALL)


def test_result_fields_are_consistent(case2):
    result = jaxarm.solve(case2, "A", n_restarts=5, seed=1, **SMALL)
    assert result.best_x.shape == (3,) and result.history.shape == (13,)
    assert result.restart_best_x.shape == (5, 3) and result.restart_history.shape == (5, 13)
    best = int(np.argmax(result.restart_best_fitness))
    assert result.best_fitness == result.restart_best_fitness[best]
    assert result.feasible == (result.best_fitness > 0)
    # history is the global best's fitness: non-decreasing under the death penalty
    assert np.all(np.diff(result.restart_history, axis=1) >= 0)
    escaped = result.restart_escape_iter >= 0
    assert np.all(result.restart_history[escaped, -1] > 0)
    assert (result.method, result.constraint, result.collision) == ("A", "death", "sampled")
    assert "fitness" in result.summary()


def test_certified_search_returns_certified_paths(case2):
    result = jaxarm.solve(case2.replace(collision="certified"), "A", n_restarts=4,
                          constraint="feasibility", **SMALL)
    assert result.feasible and result.certified and result.collision == "certified"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(constraint="soft"), r"constraint must be one of .* got 'soft'"),
        (dict(n_particles=0), r"n_particles must be >= 1, got 0"),
        (dict(n_restarts=2.5), r"n_restarts must be an integer, got 2.5"),
        (dict(seed=-1), r"seed must be an integer in \[0, 2\*\*31\), got -1"),
    ],
)
def test_bad_solve_arguments(case2, kwargs, message):
    with pytest.raises(ValueError, match=message):
        jaxarm.solve(case2, **kwargs)


def test_feasible_results_are_collision_free_by_shapely(case2):
    from test_geometry import oracle_separation

    result = jaxarm.solve(case2, "A", n_restarts=6, constraint="feasibility", **SMALL)
    feasible = result.restart_best_violation == 0
    assert feasible.any()
    r = np.linspace(0.0, 1.0, case2.n_samples)
    theta = jaxarm.joint_path(case2, result.restart_best_x[feasible], r)
    positions = np.asarray(jaxarm.joint_positions(case2.arm.lengths, theta), dtype=np.float64)
    _, hit = oracle_separation(case2.world, positions[..., :-1, :].reshape(-1, 2),
                               positions[..., 1:, :].reshape(-1, 2))
    assert not hit.any()


def _escape_rate(problem, method, constraint, n_restarts=200):
    result = jaxarm.solve(problem, method, n_restarts=n_restarts, constraint=constraint, seed=0)
    return float(np.mean(result.restart_escape_iter >= 0))


PAPER_3_OF_7 = wilson_interval(3, 7)  # Table 2: 3 of 7 runs escaped, per preset


def test_case_1_death_penalty_escape_is_consistent_with_the_papers_3_of_7_for_a(case1):
    rate = _escape_rate(case1, "A", "death")
    assert PAPER_3_OF_7[0] <= rate <= PAPER_3_OF_7[1], rate


@pytest.mark.parametrize("fixture", ["case2", "case3"])
def test_feasibility_rules_escape_on_cases_2_and_3(fixture, request):
    # On case 1 they do not (62 % over these 200 seeds, below the death penalty's 70 %;
    # benchmarks/RESULTS.md).
    assert _escape_rate(request.getfixturevalue(fixture), "A", "feasibility") >= 0.99


@pytest.mark.slow
@pytest.mark.parametrize("method", ["B", "C"])
def test_case_1_death_penalty_escape_is_consistent_with_the_papers_3_of_7(case1, method):
    rate = _escape_rate(case1, method, "death")
    assert PAPER_3_OF_7[0] <= rate <= PAPER_3_OF_7[1], rate


SHARDED_SCRIPT = """
import numpy as np, jax, jaxarm
assert len(jax.devices()) == 2, jax.devices()
result = jaxarm.solve(jaxarm.load_scenario("paper-case-2", collision="sampled"), "A", n_particles=8, n_iters=12,
                      n_restarts=7, seed=4, constraint="feasibility")
np.save(OUT, np.concatenate([result.restart_best_x.ravel(), result.restart_history.ravel()]))
"""


@pytest.mark.slow
def test_restarts_sharded_over_two_devices_match_one_device(case2, tmp_path):
    import os
    import subprocess
    import sys

    out = tmp_path / "two_devices.npy"
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
               JAX_PLATFORMS="cpu")
    subprocess.run([sys.executable, "-c", f"OUT = {str(out)!r}" + SHARDED_SCRIPT], env=env,
                   check=True, timeout=300)
    result = jaxarm.solve(case2, "A", n_restarts=7, seed=4, constraint="feasibility", **SMALL)
    np.testing.assert_array_equal(
        np.load(out),
        np.concatenate([result.restart_best_x.ravel(), result.restart_history.ravel()]))
