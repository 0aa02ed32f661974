"""Root conftest: ``pytest --doctest-modules jaxarm`` runs the package's docstring examples.

The examples use ``jaxarm`` (and ``np``) without importing them; the fixture below puts them in
every doctest's namespace. The run matches the test suite's (tests/conftest.py): CPU unless told
otherwise, float32, arrays of different ranks never broadcast by accident; pyproject.toml's
``filterwarnings = error`` applies to the examples as well. tests/test_docstrings.py runs the same
examples in `make test`, with this namespace.
"""

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxarm  # noqa: E402

jax.config.update("jax_numpy_rank_promotion", "raise")


@pytest.fixture(scope="session", autouse=True)
def _docstring_names(doctest_namespace):
    doctest_namespace.update(jaxarm=jaxarm, np=np)
