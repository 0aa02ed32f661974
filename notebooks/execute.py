"""Run every notebook here from top to bottom and save it with its outputs (``make notebooks``).

The notebooks are committed executed, figures inline; ``tests/test_notebooks.py`` runs them
again and checks that the committed outputs are complete.
"""

import pathlib
import sys

import nbformat
from nbclient import NotebookClient

HERE = pathlib.Path(__file__).parent


def execute(path: pathlib.Path) -> nbformat.NotebookNode:
    """``path``'s notebook after running every cell in a fresh kernel (in this folder)."""
    notebook = nbformat.read(path, as_version=4)
    NotebookClient(notebook, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(HERE)}}).execute()
    return notebook


if __name__ == "__main__":
    for path in sorted(HERE.glob("*.ipynb")):
        print(f"executing {path.name}", file=sys.stderr)
        nbformat.write(execute(path), path)
