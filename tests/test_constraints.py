"""Constraint-handling rules (``jaxarm.optim.constraints``) and the ring topology."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxarm
from jaxarm.optim import constraints, pso
from jaxarm.optim.constraints import Measured

# five paths: two free, three colliding with violations 1, 2, 4
OBJECTIVE = jnp.array([0.10, 0.20, 0.50, 0.40, 0.30])
VIOLATION = jnp.array([0.0, 0.0, 1.0, 2.0, 4.0])
MEASURED = Measured(objective=OBJECTIVE, fitness=jnp.where(VIOLATION == 0, OBJECTIVE, 0.0),
                    ranked_violation=VIOLATION, violation=VIOLATION)
N_ITERS = 100


def scores(rule, iteration=0, state=None):
    state = constraints.initial_state(MEASURED) if state is None else state
    return np.asarray(constraints.score(rule, state, MEASURED, iteration, N_ITERS))


def test_death_and_feasibility_rules_rank_as_documented():
    np.testing.assert_array_equal(scores("death"), np.float32([0.1, 0.2, 0.0, 0.0, 0.0]))
    np.testing.assert_array_equal(scores("feasibility"), np.float32([0.1, 0.2, -1, -2, -4]))


def test_epsilon_level_starts_at_the_quantile_and_reaches_zero_at_half_the_run():
    state = constraints.initial_state(MEASURED)
    # the 20 % quantile of the sorted violations [0, 0, 1, 2, 4]: index int(0.2 * 4) = 0
    assert float(state.epsilon0) == 0.0
    wider = constraints.initial_state(MEASURED._replace(ranked_violation=VIOLATION + 1.0))
    assert float(wider.epsilon0) == 1.0
    levels = [float(constraints.epsilon_level(wider, t, N_ITERS)) for t in range(N_ITERS + 1)]
    assert levels[0] == 1.0 and levels[25] == pytest.approx(0.5 ** 5)
    assert all(a >= b for a, b in zip(levels, levels[1:])) and levels[50:] == [0.0] * 51


def test_epsilon_rule_compares_by_objective_below_the_level_then_becomes_feasibility():
    state = constraints.initial_state(MEASURED)._replace(epsilon0=jnp.float32(2.0))
    # at t = 0 violations up to 2 count as free: path 2 (objective 0.5) ranks first
    np.testing.assert_array_equal(scores("epsilon", 0, state),
                                  np.float32([0.1, 0.2, 0.5, 0.4, -4]))
    assert np.argmax(scores("epsilon", 0, state)) == 2
    # from Tc = 50 on, the feasibility rules (with the objective, which is the fitness there)
    np.testing.assert_array_equal(scores("epsilon", 50, state), scores("feasibility"))


def test_penalty_rule_subtracts_lambda_times_violation_and_lambda_adapts():
    state = constraints.initial_state(MEASURED)
    balanced = float(np.mean(OBJECTIVE) / np.mean(VIOLATION))
    assert float(state.penalty0) == float(state.penalty) == pytest.approx(balanced)
    np.testing.assert_allclose(scores("penalty", 0, state), OBJECTIVE - balanced * VIOLATION,
                               rtol=1e-6)
    up = constraints.updated_state(state, jnp.bool_(False))
    assert float(up.penalty) == pytest.approx(2 * balanced)
    assert float(constraints.updated_state(up, jnp.bool_(True)).penalty) == float(up.penalty)
    for _ in range(40):  # doubling stops at 1e6 lambda(0): finite, so 0 * lambda stays 0
        up = constraints.updated_state(up, jnp.bool_(False))
    assert float(up.penalty) == pytest.approx(1e6 * balanced, rel=1e-6)
    free = constraints.initial_state(MEASURED._replace(ranked_violation=jnp.zeros(5)))
    assert float(free.penalty) == 1.0  # no colliding particle: nothing to balance


def test_the_swarm_scores_every_personal_best_under_the_rule_of_the_moment():
    def measure(x):  # free where x[0] > 0.6; objective peaks at x = (0.3, 0.3), inside
        objective = 1.0 - jnp.sum((x - 0.3) ** 2, axis=-1)
        violation = jnp.maximum(0.6 - x[:, 0], 0.0)
        return Measured(objective, jnp.where(violation == 0, objective, 0.0), violation,
                        violation)

    config = pso.PRESETS["A"]
    swarm = pso.swarm(config.params(), config.rules(), measure, -jnp.ones(2), jnp.ones(2),
                      n_particles=8, n_iters=20, constraint="epsilon")
    state, _ = jax.jit(swarm.begin)(jax.random.key(0))
    step = jax.jit(swarm.step)  # one program (op by op: 84 small ones)
    for t in range(1, 21):
        state, info = step(jax.random.key(t), state, t)
        expected = constraints.score("epsilon", state.constraint_state, state.best, t, 20)
        np.testing.assert_array_equal(np.asarray(state.best_score), np.asarray(expected))
        assert int(state.global_index) == int(np.argmax(np.asarray(state.best_score)))
    assert float(state.best.ranked_violation[state.global_index]) == 0.0  # epsilon is 0 by then


def test_ring_topology_follows_the_best_of_each_particles_neighbours():
    best_position = jnp.arange(5.0)[:, None] * jnp.ones((1, 2))
    state = pso.SwarmState(
        position=best_position, velocity=best_position, best_position=best_position,
        best=MEASURED, best_score=jnp.array([5.0, 1.0, 2.0, 0.0, 3.0]),
        global_index=jnp.int32(0), iteration=jnp.int32(0),
        constraint_state=constraints.initial_state(MEASURED), tie_key=jax.random.key(0))
    attractor = np.asarray(pso._social_attractor(state, True))[:, 0]
    # neighbours (i-1, i, i+1) mod 5 -> the index of the best score among them
    np.testing.assert_array_equal(attractor, [0, 0, 2, 4, 0])
    np.testing.assert_array_equal(np.asarray(pso._social_attractor(state, False)), 0)


@pytest.mark.parametrize("rule", ["epsilon", "penalty"])
def test_new_rules_and_the_ring_run_everywhere_and_repeat_bit_for_bit(case2, rule):
    ring = jaxarm.PSOConfig(topology="ring")
    small = dict(n_particles=8, n_iters=12, seed=3)  # the sizes other tests compile
    one = jaxarm.solve(case2, ring, n_restarts=5, constraint=rule, **small)
    again = jaxarm.solve(case2, ring, n_restarts=9, constraint=rule, **small)
    np.testing.assert_array_equal(one.restarts.best_x, again.restarts.best_x[:5])
    studied = jaxarm.escape_study(case2, [f"A:{rule}"], n_restarts=5, **small)
    plain = jaxarm.solve(case2, "A", n_restarts=5, constraint=rule, **small)
    np.testing.assert_array_equal(studied.method(f"A:{rule}").outcome.best_x, plain.restarts.best_x)
    # the reported fitness is the paper's whatever the rule: 1 / distance of free paths
    fitness = jaxarm.fitness(case2, plain.restarts.best_x)
    np.testing.assert_allclose(plain.restarts.best_fitness, fitness, rtol=1e-6)


def test_rules_compare_colliding_paths_by_depth_times_distance(case2):
    # Two colliding paths of case 2: a shallow and long one, a deep and short one whose depth
    # times distance is the smaller. A swarm that cannot move (no pull, no initial speed) keeps
    # as global best the particle the rule ranks first.
    x = np.random.default_rng(0).uniform(-300.0, 300.0, (256, case2.n_free)).astype(np.float32)
    depth = np.asarray(jaxarm.violation(case2, x))
    length = np.asarray(jaxarm.travelling_distance(case2, x))
    colliding = np.flatnonzero(depth > 0)
    deep_short = colliding[np.argmin((depth * length)[colliding])]
    shallower = colliding[depth[colliding] < depth[deep_short]]
    shallow_long = shallower[np.argmax(length[shallower])]
    assert depth[shallow_long] * length[shallow_long] > depth[deep_short] * length[deep_short]
    still = jaxarm.PSOConfig(cognitive_coeff=0.0, social_coeff=0.0)
    particles = np.stack([x[shallow_long]] + [x[deep_short]] * 7)
    result = jaxarm.solve(case2, still, n_particles=8, n_iters=12, n_restarts=5, seed=3,
                          constraint="feasibility", init_particles=particles)
    np.testing.assert_array_equal(result.restarts.best_x,
                                  np.broadcast_to(x[deep_short], result.restarts.best_x.shape))
