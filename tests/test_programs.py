"""``jaxarm._compile.jit.jit``: CPU compiler options at the top level, a plain jit inside a trace."""

import logging

import jax
import numpy as np

import jaxarm
from jaxarm._compile import jit as jit_lib


def test_programs_run_alone_and_inside_a_callers_jit_and_vmap_alike(case2):
    x = np.array([[66.7388, -28.1028, -9.8855], [0.0, 0.0, 0.0]], np.float32)
    alone = np.asarray(jaxarm.fitness(case2, x))
    assert alone[0] > 0.1 and alone[1] == 0  # a published free path; one through the circle
    # constants only inside a caller's jit: compiler options there would be refused by JAX
    inside_jit = jax.jit(lambda: jaxarm.fitness(case2, x))()
    inside_vmap = jax.vmap(lambda row: jaxarm.fitness(case2, row))(x)
    np.testing.assert_array_equal(np.asarray(inside_jit), alone)
    np.testing.assert_array_equal(np.asarray(inside_vmap), alone)


def _compiler_options_carried_by(lowered) -> dict:
    """The compiler options a ``jax.stages.Lowered`` will compile with. JAX has no public way to
    read them: ``Lowered`` and ``Compiled`` expose none, and the option's effect is not
    observable through them either (on CPU ``Compiled.as_text()`` is the same HLO at LLVM
    optimisation levels 1 and 2, and ``memory_analysis()`` reports no generated code size).
    So this is the one place the tests read a private attribute of JAX."""
    return dict(lowered._lowering._compiler_options_kvs or ())


def test_top_level_programs_carry_the_cpu_options_and_forward_jit_attributes():
    square = jit_lib.jit(lambda v: v * v)
    assert square.programs_made() == 0
    assert float(square(3.0)) == 9.0 and square.programs_made() == 1
    options = _compiler_options_carried_by(square.lower(2.0))  # forwarded to the top-level jit
    nested = _compiler_options_carried_by(square._nested.lower(2.0))
    assert nested == {}
    if jax.default_backend() == "cpu":
        assert options == {"xla_backend_optimization_level": 1}
    else:
        assert options == {}
    assert float(jax.jit(lambda v: square(v) + 1.0)(2.0)) == 5.0  # inside a caller's trace


def _cube(v):
    return v * v * v


def test_programs_made_counts_new_top_level_programs_only():
    cube = jit_lib.jit(_cube)
    assert float(cube(2.0)) == 8.0 and float(cube(3.0)) == 27.0
    assert cube.programs_made() == 1  # a second value of the same shape: the same program
    np.testing.assert_array_equal(cube(np.ones(2, np.float32)), np.ones(2, np.float32))
    assert cube.programs_made() == 2  # a new shape: a new program
    assert float(jax.jit(lambda v: cube(v) + 1.0)(np.float32(2.0))) == 9.0
    assert float(jax.vmap(cube)(np.ones(3, np.float32))[0]) == 1.0
    assert cube.programs_made() == 2  # inside a caller's trace: the caller's program
    again = jit_lib.jit(_cube)
    assert float(again(2.0)) == 8.0 and again.programs_made() == 1  # a count of its own
    assert cube.programs_made() == 2


def _power(v, exponent, optimise=False):
    return v ** exponent


def test_a_program_compiles_at_xla_default_level_where_its_caller_sets_the_flag():
    power = jit_lib.jit(_power, static_argnames=("exponent", "optimise"), level_flag="optimise")
    fast = _compiler_options_carried_by(power.lower(2.0, exponent=3, optimise=True))
    usual = _compiler_options_carried_by(power.lower(2.0, exponent=3, optimise=False))
    unset = _compiler_options_carried_by(power.lower(2.0, exponent=2))
    assert fast == {}
    assert usual == unset == ({"xla_backend_optimization_level": 1}
                              if jax.default_backend() == "cpu" else {})
    assert float(power(2.0, exponent=3, optimise=True)) == 8.0
    assert float(power(2.0, exponent=2)) == 4.0
    assert power.programs_made() == 3  # (3, True), (3, False) and (2, unset): each traced once
    # inside a caller's trace
    assert float(jax.jit(lambda v: power(v, exponent=3, optimise=True))(2.0)) == 8.0


def test_the_certified_search_compiles_at_xla_default_level_where_it_screens_windows():
    from jaxarm.checks.evaluate import compiles_best_at_default_level
    assert compiles_best_at_default_level(jaxarm.load_scenario("polygon-field").spec)
    assert not compiles_best_at_default_level(
        jaxarm.load_scenario("polygon-field", collision="sampled").spec)
    assert not compiles_best_at_default_level(jaxarm.load_scenario("paper-case-1").spec)


def test_a_first_certify_says_that_it_compiles(caplog, case2):
    """``jaxarm.compile`` logs when the collision check starts and ends compiling (a problem
    shape no other test uses, so this process has not made its program yet)."""
    problem = case2.replace(collision="certified", n_samples=37)
    x = [66.7388, -28.1028, -9.8855]
    with caplog.at_level(logging.INFO, logger="jaxarm.compile"):
        jaxarm.certify(problem, x)
    said = [record.getMessage() for record in caplog.records]
    assert any(m.startswith("compiling the collision check") for m in said), said
    assert any(m.startswith("compiled the collision check in ") for m in said), said
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="jaxarm.compile"):
        jaxarm.certify(problem, x)  # made already: nothing to say
    assert not caplog.records


def test_the_compile_timer_counts_nested_spans_once():
    from jaxarm._compile.timing import CompileTimer

    timer = CompileTimer()
    timer._spans += [(2.0, 3.0), (1.0, 4.0), (6.0, 7.5)]  # an inner trace ends first
    assert timer.seconds == 4.5
