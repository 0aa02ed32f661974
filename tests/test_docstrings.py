"""The examples in docstrings run and print what they show (modules whose examples are quick)."""

import doctest
import importlib

import jax
import jax.numpy as jnp
import pytest

import jaxarm

MODULES = ["jaxarm.stats", "jaxarm.optim.constraints", "jaxarm.optim.pso", "jaxarm.feasible",
           "jaxarm.trajectory"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    globs = vars(module) | {"jaxarm": jaxarm, "jax": jax, "jnp": jnp}
    result = doctest.testmod(module, globs=globs, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
