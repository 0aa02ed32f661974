"""``jaxarm._compile.jit.jit``: CPU compiler options at the top level, a plain jit inside a trace."""

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


def test_top_level_programs_carry_the_cpu_options_and_forward_jit_attributes():
    square = jit_lib.jit(lambda v: v * v)
    assert float(square(3.0)) == 9.0 and square._cache_size() == 1  # jax.jit's own attribute
    options = dict(square.lower(2.0)._lowering._compiler_options_kvs or ())
    nested = dict(square._nested.lower(2.0)._lowering._compiler_options_kvs or ())
    assert nested == {}
    if jax.default_backend() == "cpu":
        assert options == {"xla_backend_optimization_level": 1}
    else:
        assert options == {}
    assert float(jax.jit(lambda v: square(v) + 1.0)(2.0)) == 5.0  # inside a caller's trace
