"""The package's shape, read from its source: which layer imports which, and sizes.

Data flows one way (the package docstring): ``_compile`` knows nothing of arms, the optimisers
see a problem only through ``jaxarm.checks.evaluate``, and no function or certified-check
module grows past what a reader takes in at once.
"""

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "jaxarm"
MAX_FUNCTION_LINES = 100
MAX_CERTIFIED_MODULE_LINES = 400


def _modules(folder: str = "") -> list[pathlib.Path]:
    return sorted((PACKAGE / folder).rglob("*.py"))


def _imported(module: pathlib.Path) -> set[str]:
    """Every ``jaxarm...`` name the module imports, at any depth (``from a import b`` gives
    ``a.b`` too, so a submodule imported by name counts)."""
    names = set()
    for node in ast.walk(ast.parse(module.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return {name for name in names if name == "jaxarm" or name.startswith("jaxarm.")}


def _where(module: pathlib.Path) -> str:
    return str(module.relative_to(PACKAGE.parent))


def test_the_compile_layer_imports_nothing_above_it():
    for module in _modules("_compile"):
        above = {name for name in _imported(module) if not name.startswith("jaxarm._compile")}
        assert not above, f"{_where(module)} imports {sorted(above)}"


def test_the_optimisers_see_the_checks_only_through_evaluate():
    for module in _modules("optim"):
        checks = {name for name in _imported(module)
                  if name == "jaxarm.checks" or name.startswith("jaxarm.checks.")}
        assert checks <= {"jaxarm.checks.evaluate"} | {
            f"jaxarm.checks.evaluate.{name}" for name in _evaluate_names()}, (
            f"{_where(module)} imports {sorted(checks)}")


def _evaluate_names() -> set[str]:
    tree = ast.parse((PACKAGE / "checks" / "evaluate.py").read_text())
    return {node.name for node in tree.body
            if isinstance(node, (ast.FunctionDef, ast.ClassDef))}


def test_the_model_and_the_checks_import_no_optimiser():
    for folder in ("model", "checks"):
        for module in _modules(folder):
            upward = {name for name in _imported(module)
                      if name.split(".")[1] in ("optim", "search", "study", "plot", "cli",
                                                "paper", "io")}
            assert not upward, f"{_where(module)} imports {sorted(upward)}"


def test_no_function_in_the_package_is_over_100_lines():
    long = []
    for module in _modules():
        for node in ast.walk(ast.parse(module.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long.append(f"{_where(module)}:{node.lineno} {node.name} ({length} lines)")
    assert not long, long


@pytest.mark.parametrize("module", _modules("checks/certified") or [PACKAGE / "checks"],
                         ids=_where)
def test_the_certified_check_is_in_modules_of_at_most_400_lines(module):
    assert (PACKAGE / "checks" / "certified").is_dir(), "checks/certified is a package"
    n_lines = len(module.read_text().splitlines())
    assert n_lines <= MAX_CERTIFIED_MODULE_LINES, f"{_where(module)}: {n_lines} lines"


def test_the_scan_sees_imports_it_must_refuse(tmp_path):
    """The scan itself: a module importing a checks internal from optim is caught."""
    module = tmp_path / "bad.py"
    module.write_text("from jaxarm.checks import certified\nimport jaxarm.checks.collision\n")
    assert _imported(module) >= {"jaxarm.checks.certified", "jaxarm.checks.collision"}
