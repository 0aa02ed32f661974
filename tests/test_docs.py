"""The API reference builds from the docstrings without a warning and lists the public API."""

import importlib.util
import pathlib

import jaxarm

BUILDER = pathlib.Path(__file__).parents[1] / "docs" / "build_api.py"


def _builder():
    spec = importlib.util.spec_from_file_location("build_api", BUILDER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_api_reference_builds_without_warnings(tmp_path):
    assert _builder().build(tmp_path) == []
    page = (tmp_path / "jaxarm.html").read_text()
    for name in jaxarm.__all__:
        assert f'id="{name}"' in page, name
    plots = (tmp_path / "jaxarm" / "plot.html").read_text()
    assert 'id="plot_motion"' in plots
