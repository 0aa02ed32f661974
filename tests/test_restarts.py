"""The restart engine (``jaxarm.optim.restarts``): determinism, independence of the batch, jit, compiles,
sharding."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from sizes import SMALL

import jaxarm
from jaxarm.optim import constraints, pso, restarts
from jaxarm.optim.base import Optimizer, StepInfo
from jaxarm.optim.constraints import Measured
from jaxarm.optim.restarts import compiled_search


def test_same_seed_gives_bit_identical_results(case2):
    first = jaxarm.solve(case2, "A", n_restarts=4, seed=11, **SMALL)
    second = jaxarm.solve(case2, "A", n_restarts=4, seed=11, **SMALL)
    np.testing.assert_array_equal(first.restarts.best_x, second.restarts.best_x)
    np.testing.assert_array_equal(first.restarts.history, second.restarts.history)
    other = jaxarm.solve(case2, "A", n_restarts=4, seed=12, **SMALL)
    assert not np.array_equal(first.restarts.best_x, other.restarts.best_x)


@pytest.mark.parametrize("n_restarts", [3, 8])
def test_restart_results_do_not_depend_on_how_many_run(case2, n_restarts):
    few = jaxarm.solve(case2, "B", n_restarts=n_restarts, seed=3, constraint="feasibility",
                       **SMALL)
    sixteen = jaxarm.solve(case2, "B", n_restarts=16, seed=3, constraint="feasibility", **SMALL)
    np.testing.assert_array_equal(few.restarts.best_x, sixteen.restarts.best_x[:n_restarts])
    np.testing.assert_array_equal(few.restarts.escape_iter,
                                  sixteen.restarts.escape_iter[:n_restarts])
    np.testing.assert_array_equal(few.restarts.history, sixteen.restarts.history[:n_restarts])


@pytest.mark.slow
def test_jit_equals_no_jit_on_one_restart(case2):
    # eager scans run sample by sample in Python, every primitive compiled on its own: the
    # sampled check (test_problem compares the certified one with and without jit)
    case2 = case2.replace(n_samples=11, collision="sampled")
    config = pso.PRESETS["C"]
    data = restarts.SearchData(
        *(jnp.asarray(b, jnp.float32) for b in case2.bounds()), jnp.int32(0),
        jnp.zeros(1, jnp.int32), jnp.zeros((4, case2.n_free), jnp.float32), jnp.int32(0),
        jnp.int32(constraints.constraint_index("feasibility")))
    args = (case2.spec, case2.arrays, config.params(), config.rules(), data)
    sizes = dict(n_particles=4, n_iters=2)
    jitted = compiled_search(*args, **sizes)
    with jax.disable_jit():
        eager = restarts.search_restarts(*args, **sizes)
    for a, b in zip(jitted, eager):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-4)


def test_paths_left_unproved_change_no_update(case2):
    """A certified search proves only the paths whose objective beats their particle's bar
    (``base.Bar``). Stepped by hand under every rule, each update with those paths left
    unproved equals the update with every path proved, bit for bit, and paths were left."""
    # a tolerance of 1 cm: some paths end undecided, so some stop early (``Bar.free_only``;
    # asserted below: on other keys the third-order bound proved them all)
    problem = case2.replace(collision="certified", certify_tol=1.0)
    measure = restarts.path_measurement(problem.spec, problem.arrays)
    measure_every = jax.jit(jax.vmap(lambda x: measure(x)))
    measure_some = jax.jit(jax.vmap(measure))
    low, high = (jnp.asarray(b, jnp.float32) for b in problem.bounds())
    config, n_iters = pso.PRESETS["A"], SMALL["n_iters"]
    keys = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.key(5), jnp.arange(8))
    keys_at = jax.vmap(jax.random.fold_in, in_axes=(0, None))
    left, stopped = 0, 0
    for constraint in constraints.CONSTRAINTS:
        swarm = pso.swarm(config.params(), config.rules(), measure, low, high,
                          n_particles=SMALL["n_particles"], n_iters=n_iters,
                          constraint=constraints.constraint_index(constraint))
        tell = jax.jit(jax.vmap(swarm.tell, in_axes=(0, 0, 0, None)))
        state, x = jax.vmap(swarm.init)(keys_at(keys, 0))
        for iteration in range(n_iters + 1):
            some, every = measure_some(x, jax.vmap(swarm.bar)(state)), measure_every(x)
            left += int(np.sum(np.isinf(np.asarray(some.violation))))
            stopped += int(np.sum(np.isfinite(np.asarray(some.violation))
                                  & (np.asarray(some.violation) != np.asarray(every.violation))))
            expected, _ = tell(state, x, every, iteration)
            state, _ = tell(state, x, some, iteration)
            for a, b in zip(jax.tree.leaves(expected), jax.tree.leaves(state)):
                if jnp.issubdtype(a.dtype, jax.dtypes.prng_key):
                    a, b = jax.random.key_data(a), jax.random.key_data(b)
                np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=constraint)
            state, x = jax.vmap(swarm.ask)(keys_at(keys, iteration + 1), state)
    assert left > 0 and stopped > 0


def test_a_search_that_skips_proofs_returns_what_proving_all_returns(case2):
    """The restart loop with ``measure_above`` (what ``solve`` runs) against the same loop
    measuring every path in full: the same outcome, bit for bit, under two rules."""
    problem = case2.replace(collision="certified", certify_tol=1.0)
    measure = restarts.path_measurement(problem.spec, problem.arrays)
    low, high = (jnp.asarray(b, jnp.float32) for b in problem.bounds())
    config = pso.PRESETS["A"]
    keys = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(jax.random.key(2), jnp.arange(8))

    @functools.partial(jax.jit, static_argnames="skip")
    def search(constraint, skip):
        swarm = pso.swarm(config.params(), config.rules(), measure, low, high,
                          constraint=constraint, **SMALL)
        return restarts.run_restarts_of(keys, swarm, SMALL["n_iters"],
                                        measure_above=measure if skip else None)

    for constraint in ("death", "feasibility"):
        index = jnp.int32(constraints.constraint_index(constraint))
        skipping, proving = search(index, True), search(index, False)
        assert np.any(np.asarray(proving.best_violation) == 0)  # some restarts escaped
        for a, b in zip(skipping, proving):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=constraint)


def test_a_second_problem_with_the_same_sizes_does_not_recompile(case2, case3):
    jaxarm.solve(case2, "A", n_restarts=2, **SMALL)
    before = compiled_search.programs_made()
    jaxarm.solve(case3, "B", n_restarts=2, seed=5, **SMALL)  # new data, new preset, new seed
    jaxarm.solve(case2.replace(start=[5.7, 1.2, 0.7]), "C", n_restarts=2, **SMALL)
    jaxarm.solve(case2, "A", n_restarts=2, constraint="feasibility", **SMALL)  # rule is data
    jaxarm.solve(case2, "A-ring", n_restarts=2, **SMALL)  # so is the topology
    given = jaxarm.solve(case2, "A", n_restarts=2, init_particles=[[66.7, -28.1, -9.9]], **SMALL)
    assert compiled_search.programs_made() == before  # and the number of given particles
    assert given.restarts.best_fitness.min() > 0  # the given free path is a personal best


SHARDED_SCRIPT = """
import numpy as np, jax, jaxarm
assert len(jax.devices()) == 2, jax.devices()
case2 = jaxarm.load_scenario("paper-case-2", collision="sampled")
result = jaxarm.solve(case2, "A", n_particles=8, n_iters=12, n_restarts=7, seed=4,
                      constraint="feasibility")
np.save(OUT, np.concatenate([result.restarts.best_x.ravel(), result.restarts.history.ravel()]))
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
        np.concatenate([result.restarts.best_x.ravel(), result.restarts.history.ravel()]))


def test_any_optimiser_given_as_ask_and_tell_runs_in_the_restart_loop():
    """A random search (not PSO) written as a ``base.Optimizer`` plugs into
    ``run_restarts_of``, which measures its paths at one place."""
    low, high = jnp.full(2, -1.0), jnp.full(2, 1.0)
    calls = []

    def measure(x):  # feasible where x[0] > 0.5
        calls.append(x.shape)  # once per trace of the loop
        fitness = -jnp.sum((x - 0.3) ** 2, axis=-1)
        violation = jnp.where(x[:, 0] > 0.5, 0.0, 1.0)
        return Measured(fitness, fitness, violation, violation)

    def sample(key, best):
        return best, jax.random.uniform(key, (6, 2), minval=low, maxval=high)

    def tell(best, x, measured, iteration):
        row = jnp.argmax(measured.fitness)
        better = measured.fitness[row] > best[1]
        best = (jnp.where(better, x[row], best[0]), jnp.where(better, measured.fitness[row],
                                                               best[1]))
        return best, StepInfo(global_position=best[0], global_fitness=best[1],
                              global_violation=jnp.where(best[0][0] > 0.5, 0.0, 1.0),
                              global_score=best[1],
                              n_feasible=(measured.violation == 0).sum(dtype=jnp.int32))

    def init(key):
        return sample(key, (jnp.zeros(2), jnp.asarray(-jnp.inf)))

    swarm = Optimizer(init=init, tell=tell, ask=sample, measure=measure)
    run_all = jax.jit(restarts.run_restarts_of, static_argnums=(1, 2))
    outcome = jax.tree.map(lambda a: a[0], run_all(jax.random.key(0)[None], swarm, 20))
    assert calls == [(6, 2)]
    history = np.asarray(outcome.history)
    assert history.shape == (21,) and np.all(np.diff(history) >= 0)
    assert float(-np.sum((np.asarray(outcome.best_x) - 0.3) ** 2)) == pytest.approx(history[-1])
    assert float(outcome.best_fitness) == history[-1]
    escape_iter = int(outcome.escape_iter)
    assert escape_iter >= 0  # P(no sample with x[0] > 0.5 in 126) = 0.75 ** 126
    escape_fitness = -np.sum((np.asarray(outcome.escape_x) - 0.3) ** 2)
    assert escape_fitness == pytest.approx(float(history[escape_iter]))
    # several restarts in one loop: each as it runs alone, with typed or raw keys
    keys = jax.random.split(jax.random.key(1), 3)
    together = run_all(keys, swarm, 20)
    assert together.history.shape == (3, 21) and together.best_x.shape == (3, 2)
    raw = run_all(jax.random.key_data(keys), swarm, 20)
    for i in range(3):
        alone = jax.tree.map(lambda a: a[0], run_all(keys[i][None], swarm, 20))
        for field, value in alone._asdict().items():
            np.testing.assert_array_equal(getattr(together, field)[i], value)
            np.testing.assert_array_equal(getattr(raw, field)[i], value)


def test_two_processes_return_what_one_process_returns(case2, tmp_path):
    """``jaxarm --coordinator ... solve``: two local CPU processes (gloo), process 0 writes."""
    import json
    import os
    import socket
    import subprocess
    import sys

    with socket.socket() as probe:  # a free port on 127.0.0.1
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    out = tmp_path / "two_processes.json"
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    env.pop("XLA_FLAGS", None)
    processes = [subprocess.Popen(
        [sys.executable, "-m", "jaxarm", "--coordinator", f"127.0.0.1:{port}",
         "--num-processes", "2", "--process-id", str(i), "solve", "paper-case-2", "--method", "A",
         "--collision", "sampled", "--particles", "8", "--iters", "12", "--restarts", "7",
         "--seed", "4", "--constraint", "feasibility", "--json", str(out)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in (0, 1)]
    try:  # the one-process run while the two processes run
        one = jaxarm.solve(case2, "A", n_restarts=7, seed=4, constraint="feasibility", **SMALL)
        outputs = [p.communicate(timeout=300) for p in processes]
    finally:
        for p in processes:
            p.kill()  # none left behind by a failure (a finished process is left alone)
    assert [p.returncode for p in processes] == [0, 0], [err[-2000:] for _, err in outputs]
    assert f"wrote {out}" in outputs[0][0] and "fitness" in outputs[0][0]
    assert "wrote" not in outputs[1][0] and "fitness" not in outputs[1][0]  # 1 stays quiet
    two = jaxarm.Result.from_dict(json.loads(out.read_text())["result"])
    for name in one.restarts._fields:
        np.testing.assert_array_equal(getattr(two.restarts, name), getattr(one.restarts, name))
