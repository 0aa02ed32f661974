"""Every docstring example of the package runs and prints what it shows; the public entry points
each carry one.

The modules are found by walking the package (a new module's examples run without being listed
here); each runs with the names the root conftest.py gives ``pytest --doctest-modules jaxarm``
(``doctest_namespace``: ``jaxarm``, ``np``), under this suite's settings (tests/conftest.py).
"""

import doctest
import importlib
import pkgutil

import pytest

import jaxarm

# Only subpackages are imported to list the modules; each module is imported by its test.
MODULES = sorted(info.name for info in pkgutil.walk_packages(jaxarm.__path__, "jaxarm."))
ENTRY_POINTS = ["solve", "certify", "fitness", "Problem", "World", "escape_study", "Trajectory",
                "min_duration", "refine", "load_scenario", "feasible_fraction"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name, doctest_namespace):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for test in finder.find(module, name, globs=vars(module) | doctest_namespace):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0  # the runner printed each failure (pytest shows stdout)


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_entry_point_has_an_example(name):
    assert ">>>" in getattr(jaxarm, name).__doc__
