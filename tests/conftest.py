"""Shared fixtures. Tests run on CPU in float32 unless a test enters ``jax.enable_x64(True)``."""

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")
# Tests do not read or fill the user's compilation cache unless asked (tests/test_cache.py).
os.environ.setdefault("JAXARM_CACHE_DIR", "off")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import jaxarm  # noqa: E402

settings.register_profile("jaxarm", deadline=None, max_examples=40, derandomize=True)
settings.load_profile("jaxarm")

# The paper's cases under the paper's own (sampled) collision check; tests of the certified
# check say so explicitly.
@pytest.fixture(scope="session")
def case1():
    return jaxarm.load_scenario("paper-case-1", collision="sampled")


@pytest.fixture(scope="session")
def case2():
    return jaxarm.load_scenario("paper-case-2", collision="sampled")


@pytest.fixture(scope="session")
def case3():
    return jaxarm.load_scenario("paper-case-3", collision="sampled")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
