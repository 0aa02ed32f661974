"""Traced programs kept on disk (``jaxarm._compile.stored_programs``): reused by a new process, same bits, keyed
on everything the trace depends on, and plain ``jax.jit`` whenever a call cannot be keyed."""

import concurrent.futures
import json
import os
import subprocess
import sys
import threading
import time

import jax
import numpy as np
import optax
import pytest
from test_programs import _compiler_options_carried_by

import jaxarm
from jaxarm._compile import stored_programs
from jaxarm._compile.jit import jit
from jaxarm.checks import evaluate as evaluate_lib
from jaxarm.optim import refine as refine_lib

# The CLI in a new process, counting the programs it traces for storing; then the clearances
# of its restarts' paths (certify's floats: the JSON has only the best path's verdict).
CLI = """
import json, sys
import jaxarm
from jaxarm import cli
from jaxarm._compile import stored_programs
exports = []
export = stored_programs._export
stored_programs._export = lambda *a: exports.append(1) or export(*a)
assert cli.main(sys.argv[1:]) == 0
x = json.loads(open(sys.argv[-1]).read())["result"]["restarts"]["best_x"]
clearance = jaxarm.certify(jaxarm.load_scenario("paper-case-2"), x).clearance.tolist()
print(json.dumps({"exports": len(exports), "clearance": clearance}))
"""
SOLVE = ["solve", "paper-case-2", "--collision", "sampled", "--particles", "8", "--iters", "12",
         "--restarts", "3", "--seed", "1", "--refine", "all"]  # search, refine, certify


def _solve(folder, out, flags=(), first_line: str = "") -> tuple[int, dict]:
    """A CLI solve in a new process with ``$JAXARM_CACHE_DIR`` set to ``folder``, writing JSON
    to ``out``: (programs it traced for storing, the result without its time and with the
    clearances of its restarts' paths)."""
    done = subprocess.run([sys.executable, "-c", first_line + CLI, *flags, *SOLVE, "--json",
                           str(out)], capture_output=True, text=True, timeout=300, check=True,
                          env=dict(os.environ, JAXARM_CACHE_DIR=str(folder)))
    printed = json.loads(done.stdout.strip().splitlines()[-1])
    result = json.loads(out.read_text())["result"]
    del result["seconds"]
    for stage in result["stages"]:  # timings
        del stage["seconds"], stage["time_left"]
    return printed["exports"], dict(result, clearance=printed["clearance"])


def test_the_cli_keeps_programs_a_new_process_runs_with_the_bits_of_plain_jit(tmp_path):
    """The compilation cache and the stored traces, on by default in the CLI and off with
    ``--no-cache`` (tests/test_cache.py tests where the cache lives)."""
    folder = tmp_path / "xla"
    with concurrent.futures.ThreadPoolExecutor(2) as pool:  # two independent processes
        # --no-cache: every program traced and compiled by jax.jit, nothing kept
        plain_run = pool.submit(_solve, tmp_path / "off", tmp_path / "plain.json",
                                ["--no-cache"])
        first_run = pool.submit(_solve, folder, tmp_path / "first.json")
        (plain_exports, plain), (first_exports, first) = plain_run.result(), first_run.result()
    assert not (tmp_path / "off").exists()
    compiled = sorted(p.name for p in folder.iterdir())
    assert any(name.startswith("jit_search_restarts") for name in compiled), compiled
    stored = sorted(p.name for p in (folder / "traces").iterdir())
    # another entry point (more of jaxarm imported) finds the same programs
    second_exports, second = _solve(folder, tmp_path / "second.json",
                                    first_line="import jaxarm.paper.report, jaxarm.plot")
    assert plain_exports == 0 and first_exports >= 3  # search, refine, certify at least
    assert second_exports == 0  # nothing traced: every program came from the folder
    assert sorted(p.name for p in (folder / "traces").iterdir()) == stored
    assert sorted(p.name for p in folder.iterdir()) == compiled  # nothing compiled anew
    assert first["best_fitness"] > first["pso_best_fitness"]  # refine moved the best path
    assert first == plain and second == plain


def _evaluate_call(problem, x):
    static_names = frozenset({"spec"})
    return stored_programs.split_call(evaluate_lib.evaluate, static_names, (problem.spec, problem.arrays,
                                                                  x), {})


def test_keys_change_with_statics_and_shapes(case2):
    x = np.zeros((4, case2.n_free), np.float32)

    def key(problem=case2, rows=x):
        return stored_programs._disk_key("evaluate", _evaluate_call(problem, rows), None)

    same = key()
    assert key() == same
    assert key(rows=np.zeros((8, case2.n_free), np.float32)) != same
    assert key(problem=case2.replace(degree=7), rows=np.zeros((4, 6), np.float32)) != same
    assert key(problem=case2.replace(collision="certified")) != same
    assert key(problem=case2.replace(margin=1.0)) != same  # with_margin changes the check
    assert key(problem=case2.replace(margin=0.5)) == key(problem=case2.replace(margin=1.0))


def test_calls_that_cannot_be_keyed_run_as_plain_jit(case2, monkeypatch, tmp_path):
    monkeypatch.setattr(stored_programs, "_directory", tmp_path)
    assert stored_programs.directory() == tmp_path and stored_programs.usable()
    x = np.array([[66.7388, -28.1028, -9.8855]], np.float32)
    sgd = optax.sgd(0.01)
    assert stored_programs.split_call(refine_lib._refine_rows, frozenset({"optimizer"}),
                             (None, None, x, sgd, 3, 1.0, 0.5, 0.25), {}) is None
    assert stored_programs.split_call(evaluate_lib.evaluate, frozenset({"spec"}),
                             (case2.spec, case2.arrays, "not an array"), {}) is None
    custom = jaxarm.refine(case2, x, n_steps=5, optimizer=sgd)
    assert not list(tmp_path.iterdir())  # nothing stored for a custom optimizer
    assert custom.fitness[0] >= custom.initial_fitness[0] > 0.1
    # a storable program of its own (jaxarm's are already in this process's memory)
    evaluate = jit(evaluate_lib.evaluate, static_argnums=0, storable=True)
    assert evaluate.programs_made() == 0  # counted per program, not in jax.jit's shared cache
    evaluate(case2.spec, case2.arrays, x)
    assert len(list(tmp_path.iterdir())) == 1
    stored_programs.keep_in(None)  # the off switch (monkeypatch puts the run's folder back after)
    assert stored_programs.directory() is None and not stored_programs.usable()
    evaluate(case2.spec, case2.arrays, np.repeat(x, 2, axis=0))  # traced by jax.jit only
    # one stored program, then one traced by jax.jit
    assert len(list(tmp_path.iterdir())) == 1 and evaluate.programs_made() == 2


def test_a_damaged_stored_trace_is_traced_again_and_replaced(case2, monkeypatch, tmp_path):
    monkeypatch.setattr(stored_programs, "_directory", tmp_path)
    x = np.array([[66.7388, -28.1028, -9.8855], [0.0, 0.0, 0.0]], np.float32)
    call = _evaluate_call(case2, x)

    def run():  # XLA's default options on both sides
        stored = stored_programs.stored_program(evaluate_lib.evaluate, "evaluate", call, None)
        return jax.tree.unflatten(stored.out_tree, stored.call(*call.leaves))

    expected = jax.jit(evaluate_lib.evaluate, static_argnums=0)(case2.spec, case2.arrays, x)
    first = run()
    (path,) = tmp_path.iterdir()
    path.write_bytes(b"not a stored program")
    again = run()
    assert stored_programs._load(path) is not None  # replaced by a good one
    for a, b, c in zip(expected, first, again):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        np.testing.assert_array_equal(np.asarray(a), np.asarray(c))


def _doubled_on_the_host(v):
    return jax.pure_callback(lambda a: np.asarray(a) * 2, jax.ShapeDtypeStruct(v.shape, v.dtype),
                             v)


def test_a_program_export_refuses_runs_as_plain_jit_with_a_warning(monkeypatch, tmp_path):
    monkeypatch.setattr(stored_programs, "_directory", tmp_path)
    program = jit(_doubled_on_the_host, storable=True)  # a host callback: export refuses it
    v = np.arange(3.0, dtype=np.float32)
    with pytest.warns(RuntimeWarning, match="_doubled_on_the_host is traced in every process"):
        np.testing.assert_array_equal(program(v), 2 * v)
    np.testing.assert_array_equal(program(v + 1), 2 * (v + 1))  # no second warning
    assert not list(tmp_path.iterdir()) and program.programs_made() == 1


def test_threads_asking_for_one_program_together_trace_and_compile_it_once(
        case2, monkeypatch, tmp_path):
    """The report runs its sections on threads; two that need the same program make it once."""
    monkeypatch.setattr(stored_programs, "_directory", tmp_path)
    exports, export = [], stored_programs._export

    def slow_export(*args):  # the second thread arrives while the first is still tracing
        exports.append(1)
        time.sleep(0.3)
        return export(*args)

    monkeypatch.setattr(stored_programs, "_export", slow_export)
    evaluate = jit(evaluate_lib.evaluate, static_argnums=0, storable=True)
    x = np.array([[66.7388, -28.1028, -9.8855]], np.float32)
    results = [None, None]
    assert evaluate.programs_made() == 0

    def call(i):
        results[i] = evaluate(case2.spec, case2.arrays, x)

    threads = [threading.Thread(target=call, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(exports) == 1 and evaluate.programs_made() == 1
    assert len(list(tmp_path.iterdir())) == 1
    for a, b in zip(*results):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def _scaled(v, factor, optimise):
    return v * factor


def test_stored_programs_keep_the_level_their_static_arguments_choose(monkeypatch, tmp_path):
    monkeypatch.setattr(stored_programs, "_directory", tmp_path)
    scaled = jit(_scaled, static_argnames=("factor", "optimise"), storable=True,
                 level_flag="optimise")
    v = np.arange(3.0, dtype=np.float32)
    np.testing.assert_array_equal(scaled(v, factor=3, optimise=True), 3 * v)
    np.testing.assert_array_equal(scaled(v, factor=2, optimise=False), 2 * v)
    assert len(list(tmp_path.iterdir())) == 2  # one stored program per factor
    on_cpu = jax.default_backend() == "cpu"
    for (statics, _, _), stored in scaled._stored.items():
        options = _compiler_options_carried_by(stored.call.lower(v))
        at_default = dict(statics)["optimise"] or not on_cpu
        assert options == ({} if at_default else {"xla_backend_optimization_level": 1})
