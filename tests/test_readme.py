"""The Python in the README and the user guide runs as written (at smaller study sizes)."""

import os
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]
SMALLER = {r"n_restarts=\d+": "n_restarts=3"}  # studies of hundreds of seeds belong to benchmarks


def python_blocks(page: pathlib.Path) -> str:
    """The page's ```python blocks, in order, as one program."""
    return "\n".join(re.findall(r"^```python\n(.*?)^```$", page.read_text(), flags=re.S | re.M))


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_page_python_runs(page, tmp_path, monkeypatch):
    program = python_blocks(page)
    for pattern, replacement in SMALLER.items():
        program = re.sub(pattern, replacement, program)
    monkeypatch.chdir(tmp_path)  # files the examples write land here
    exec(compile(program, str(page), "exec"), {"__name__": "__readme__"})
    written = set(os.listdir(tmp_path))
    for name in re.findall(r'savefig\("([^"]+)"\)|to_csv\("([^"]+)"', program):
        assert set(filter(None, name)) <= written, name
