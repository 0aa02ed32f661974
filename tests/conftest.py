"""Shared fixtures. Tests run on CPU in float32 unless a test enters ``jax.enable_x64(True)``."""

import os
import shutil
import tempfile

os.environ.setdefault("JAX_PLATFORMS", "cpu")
# One scratch compilation cache per test run, shared by its processes (the xdist workers and
# the subprocesses tests start, which inherit the environment): a program one of them compiled
# the others load instead of compiling it again. The user's own cache is never read or written
# (tests/test_cache.py points its processes at folders of its own). The first process (xdist's
# controller, or pytest without xdist) creates it and removes it at the end.
_OWN_CACHE = "JAXARM_TEST_RUN_CACHE" not in os.environ
if _OWN_CACHE:
    os.environ["JAXARM_TEST_RUN_CACHE"] = tempfile.mkdtemp(prefix="jaxarm-test-xla-")
os.environ["JAXARM_CACHE_DIR"] = os.environ["JAXARM_TEST_RUN_CACHE"]

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import jaxarm  # noqa: E402

jaxarm.enable_compilation_cache()
# Arrays of different ranks never broadcast by accident (programs.rank_promotion_allowed marks
# the code that means to: the world's polygon kernels, evosax's strategies).
jax.config.update("jax_numpy_rank_promotion", "raise")


def pytest_unconfigure(config):
    if _OWN_CACHE:
        shutil.rmtree(os.environ["JAXARM_TEST_RUN_CACHE"], ignore_errors=True)


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
