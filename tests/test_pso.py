"""The PSO engine (``jaxarm.optim.pso``): velocity rules, presets, bests, ties, NaN."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import choices
from jaxarm.optim import constraints, methods, pso, restarts
from jaxarm.optim.constraints import Measured

LOW, HIGH = jnp.full(2, -1.0), jnp.full(2, 1.0)
# One swarm size wherever the size does not matter: these swarms run op by op, and each new
# size compiled every operation of a step again (this file: 17 s -> 6-7 s on one core).
PARTICLES = 6


def make_swarm(config, measure_fn, n_particles, n_iters, low=LOW, high=HIGH,
               constraint="death"):
    return pso.swarm(config.params(), config.rules(), measure_fn, low, high,
                     n_particles=n_particles, n_iters=n_iters, constraint=constraint)


def sphere(x):
    """Maximise -|x - 0.3|^2; feasible where x[0] > 0.5."""
    fitness = -jnp.sum((x - 0.3) ** 2, axis=-1)
    violation = jnp.where(x[:, 0] > 0.5, 0.0, 1.0)
    return Measured(objective=fitness, fitness=fitness, ranked_violation=violation,
                    violation=violation)


def test_presets_are_the_papers_table_2():
    a, b, c = (pso.PRESETS[name] for name in "ABC")
    assert (a.velocity_rule, a.cognitive_coeff, a.social_coeff) == ("inertia", 1.5, 1.5)
    assert (b.velocity_rule, b.cognitive_coeff, b.social_coeff) == ("inertia", 0.5, 0.5)
    assert (a.inertia_start, a.inertia_end) == (b.inertia_start, b.inertia_end) == (1.0, 0.0)
    assert (c.velocity_rule, c.cognitive_coeff, c.social_coeff) == ("constriction", 3.0, 2.0)
    assert round(c.constriction, 4) == 0.3820
    assert a.constriction == b.constriction == 1.0
    # the README's slower ring: PSOConfig's defaults are preset A's
    assert (pso.PSOConfig(topology="ring", inertia_end=0.4)
            == a._replace(topology="ring", inertia_end=0.4))


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
    swarm = make_swarm(config, sphere, n_particles=PARTICLES, n_iters=10)
    state, _ = swarm.begin(jax.random.key(1))
    # Make personal bests differ from positions so every term of the rule matters.
    state = state._replace(best_position=state.best_position * 0.5, global_index=jnp.int32(3))
    key = jax.random.key(7)
    new, _ = swarm.step(key, state, 1)

    beta_key, _ = jax.random.split(key)
    shape = (PARTICLES, 2) if config.beta == "dimension" else (PARTICLES, 1)
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
    swarm = make_swarm(config, sphere, n_particles=PARTICLES, n_iters=5)
    state, _ = swarm.begin(jax.random.key(2))
    for t in range(5):
        previous = state
        state, info = swarm.step(jax.random.key(t), state, t + 1)
        score = np.asarray(sphere(state.position).fitness)  # the death rule: score = fitness
        improved = score > np.asarray(previous.best_score)
        np.testing.assert_array_equal(np.asarray(state.best_score),
                                      np.where(improved, score, previous.best_score))
        assert int(state.global_index) == int(np.argmax(np.asarray(state.best_score)))
        assert float(info.global_score) == float(np.max(np.asarray(state.best_score)))
        np.testing.assert_array_equal(np.asarray(info.global_position),
                                      np.asarray(state.best_position[state.global_index]))


def all_infeasible(x):
    zero = jnp.zeros(x.shape[0])
    return Measured(objective=zero, fitness=zero, ranked_violation=zero + 1.0,
                    violation=zero + 1.0)


def test_all_infeasible_death_penalty_keeps_particle_zero_as_global_best():
    """Paper-faithful MATLAB `max` tie-breaking: the documented evosax PR #109 behaviour."""
    config = pso.PRESETS["A"]
    swarm = make_swarm(config, all_infeasible, n_particles=PARTICLES, n_iters=4)
    state, _ = swarm.begin(jax.random.key(3))
    start = np.asarray(state.position)
    for t in range(4):
        state, info = swarm.step(jax.random.key(t), state, t + 1)
        assert int(state.global_index) == 0
        np.testing.assert_array_equal(np.asarray(state.best_position), start)
        assert int(info.n_feasible) == 0


def test_random_tie_break_spreads_the_global_best():
    config = pso.PSOConfig(tie_break="random")
    swarm = make_swarm(config, all_infeasible, n_particles=PARTICLES, n_iters=1)
    chosen = set()
    for seed in range(20):
        state, _ = swarm.begin(jax.random.key(seed))
        chosen.add(int(state.global_index))
    assert len(chosen) >= 4


def test_nan_and_inf_never_become_a_best():
    def poisoned(x):
        fitness = jnp.where(x[:, 0] > 0, jnp.nan, -jnp.sum(x**2, axis=-1))
        fitness = fitness.at[1].set(jnp.inf)
        violation = jnp.where(jnp.isfinite(fitness), 0.0, 1.0)
        return Measured(objective=fitness, fitness=fitness, ranked_violation=violation,
                        violation=violation)

    config = pso.PSOConfig("original", 2.0, 2.0, init_velocity=5.0)  # diverges quickly
    swarm = make_swarm(config, poisoned, n_particles=PARTICLES, n_iters=30)
    state, _ = swarm.begin(jax.random.key(4))
    for t in range(30):
        state, info = swarm.step(jax.random.key(t), state, t + 1)
        assert np.all(np.isfinite(np.asarray(state.best_position)))
        assert np.isfinite(float(info.global_score))
        best = int(state.global_index)
        assert float(state.best_score[best]) > -np.inf


def test_escape_iteration_is_the_first_with_a_feasible_particle():
    """The restart loop's escape iteration is the first update (stepped by hand with the
    loop's keys) at which a particle is feasible."""
    config = pso.PRESETS["A"]
    low, high = jnp.full(2, -1.0), jnp.full(2, 0.0)  # the initial swarm is all infeasible
    swarm = make_swarm(config, sphere, n_particles=PARTICLES, n_iters=40, low=low, high=high)
    key = jax.random.key(5)
    state, info = swarm.begin(jax.random.fold_in(key, 0))
    assert int(info.n_feasible) == 0
    first = None
    for t in range(1, 41):
        state, info = swarm.step(jax.random.fold_in(key, t), state, t)
        if first is None and int(info.n_feasible) > 0:
            first = t
    outcome = restarts.run_restarts_of(key[None], swarm, 40)
    assert first is not None and int(outcome.escape_iter[0]) == first


def test_bad_configs_name_the_field():
    with pytest.raises(ValueError, match=r"velocity_rule must be one of .* got 'fast'"):
        methods.parse_method(pso.PSOConfig(velocity_rule="fast"))
    with pytest.raises(ValueError, match=r"constriction needs .* > 4, got 1.0 \+ 2.0"):
        methods.parse_method(pso.PSOConfig("constriction", 1.0, 2.0))
    with pytest.raises(ValueError, match=r"cognitive_coeff must be a finite number >= 0"):
        methods.parse_method(pso.PSOConfig(cognitive_coeff=float("nan")))
    for name in ("D", "D-ring", "A-star", "a"):
        with pytest.raises(ValueError, match=r"method must be one of \('A', 'B', 'C', 'A-ring'"):
            methods.parse_method(name)


def test_ring_names_are_the_presets_with_the_ring_topology():
    for name in choices.PRESET_NAMES:
        assert methods.parse_method(name + "-ring").config == pso.PRESETS[name]._replace(topology="ring")
        assert (methods.parse_method(name + "-global-ring").config
                == pso.PRESETS[name]._replace(topology="global-ring"))
        assert methods.parse_method(name).config.topology == "global"
    variant, = methods.parse_methods(["A-ring:epsilon"], "death")
    assert variant == ("A-ring:epsilon", pso.PRESETS["A"]._replace(topology="ring"), "epsilon")
    variant, = methods.parse_methods(["B-global-ring:epsilon"], "death")
    assert variant.config == pso.PRESETS["B"]._replace(topology="global-ring")


def test_fields_in_brackets_change_a_named_method():
    assert (methods.parse_method("A-ring[inertia_end=0.4]").config
            == pso.PRESETS["A"]._replace(topology="ring", inertia_end=0.4))
    assert (methods.parse_method("C[ tie_break = random , velocity_clamp=0.05]").config
            == pso.PRESETS["C"]._replace(tie_break="random", velocity_clamp=0.05))
    assert methods.parse_method("A[velocity_clamp=none]").config.velocity_clamp is None
    for method, message in [("A[inertia_end=x]", "inertia_end must be a number, got 'x'"),
                            ("A[speed=1]", "must be FIELD=VALUE with FIELD one of"),
                            ("A[]", "must be FIELD=VALUE"),
                            ("A[inertia_end]", "must be FIELD=VALUE"),
                            ("A[inertia_end=0.4", "the brackets must close at its end"),
                            ("A[", "the brackets must close at its end"),
                            ("A[inertia_end=0.4]x", "the brackets must close at its end"),
                            ("D[inertia_end=0.4]", "method must be one of"),
                            ("A[beta=1,beta=2]", "beta is changed twice"),
                            ("A[inertia_end=-1]", "inertia_end must be a finite number >= 0"),
                            ("A[social_coeff=1e300]",
                             "social_coeff must be within +-3.40282e+38, got 1e+300"),
                            ("A[velocity_clamp=1e-300]", "velocity_clamp must be 0 or at least"),
                            ("A[topology=star]", "topology must be one of")]:
        with pytest.raises(ValueError, match=re.escape(message)):
            methods.parse_method(method)


def test_global_ring_follows_the_global_best_then_the_ring():
    """With 40 iterations, 5 % is 2: updates 1 and 2 as "global", every later one as "ring"."""
    global_, ring, both = (make_swarm(pso.PRESETS["A"]._replace(topology=t), sphere,
                                      n_particles=PARTICLES, n_iters=40)
                           for t in ("global", "ring", "global-ring"))
    state, _ = both.begin(jax.random.key(3))
    for t in range(1, 6):
        key = jax.random.key(100 + t)
        expected, _ = (global_ if t <= 2 else ring).step(key, state, t)
        other, _ = (ring if t <= 2 else global_).step(key, state, t)
        state, _ = both.step(key, state, t)
        np.testing.assert_array_equal(state.position, expected.position)
        assert not np.array_equal(state.position, other.position)  # the two really differ


def test_presets_and_choices_agree():
    assert tuple(pso.PRESETS) == choices.PRESET_NAMES
    for config in pso.PRESETS.values():
        assert config.validate() is config
        assert config.velocity_rule in choices.VELOCITY_RULES
    params = pso.PRESETS["C"].params()
    assert float(params.constriction) == pytest.approx(pso.PRESETS["C"].constriction)
    assert pso.PRESETS["A"].rules() == pso.SwarmRules(tie_break="first", beta="dimension")
    with pytest.raises(ValueError, match=r"constraint must be one of \('death', 'feasibility', "
                                         r"'epsilon', 'penalty'\), got 'soft'"):
        constraints.constraint_index("soft")
    with pytest.raises(ValueError,
                       match=r"topology must be one of \('global', 'ring', 'global-ring'\)"):
        methods.parse_method(pso.PSOConfig(topology="star"))
