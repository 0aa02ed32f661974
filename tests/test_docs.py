"""The user guide and API reference build strictly (any warning fails), and the reference
covers the public API."""

import os
import pathlib
import re
import subprocess
import sys

import jaxarm

ROOT = pathlib.Path(__file__).parents[1]
API = ROOT / "docs" / "api"


def test_api_reference_names_every_public_name():
    documented = set()
    for page in API.glob("*.md"):
        documented |= set(re.findall(r"^::: ([\w.]+)$", page.read_text(), flags=re.M))
    for name in jaxarm.__all__:
        defined_as = jaxarm._RENAMED.get(name, name)
        assert f"{jaxarm._EXPORTS[name]}.{defined_as}" in documented, name
    assert "jaxarm.plot" in documented


def test_user_guide_builds_strictly(tmp_path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    built = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                            str(tmp_path)], cwd=ROOT, env=env, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr[-3000:]
    solve_page = (tmp_path / "api" / "search" / "index.html").read_text()
    assert 'id="jaxarm.search.solve"' in solve_page
    notebook = (tmp_path / "notebooks" / "quickstart" / "index.html").read_text()
    assert "image/png" in notebook or "<img" in notebook  # rendered with its figures
