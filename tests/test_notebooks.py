"""Both notebooks are committed executed, with their figures inline, and still run from top to
bottom (``make notebooks`` re-executes them)."""

import pathlib

import nbformat
import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


def test_there_are_two_notebooks():
    assert {p.name for p in NOTEBOOKS} == {"quickstart.ipynb", "paper_reproduction.ipynb"}


def figure_cells(notebook) -> list[int]:
    return [i for i, cell in enumerate(notebook.cells) if cell.cell_type == "code"
            and any("image/png" in out.get("data", {}) for out in cell.outputs)]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_committed_executed_with_figures_and_no_warnings(path):
    notebook = nbformat.read(path, as_version=4)
    code = [c for c in notebook.cells if c.cell_type == "code" and c.source.strip()]
    assert all(c.execution_count is not None for c in code), "commit it executed"
    assert figure_cells(notebook), "no inline figure"
    for cell in code:
        for out in cell.outputs:
            data = out.get("data", {})
            text = out.get("text", "") + str(data.get("text/plain", ""))
            assert "Warning" not in text and out.output_type != "error", text[:200]
            # a figure printed as text instead of drawn (its PNG beside the text is fine)
            assert "<Figure size" not in text or "image/png" in data, text[:200]


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes_and_draws_the_figures_it_was_committed_with(path, tmp_path):
    from nbclient import (
        NotebookClient,  # the notebooks extra (make test-all installs it)
    )

    committed = nbformat.read(path, as_version=4)
    notebook = nbformat.read(path, as_version=4)
    # nbclient raises CellExecutionError on the first failing cell
    NotebookClient(notebook, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    unexecuted = [i for i, c in enumerate(notebook.cells)
                  if c.cell_type == "code" and c.source.strip() and c.execution_count is None]
    assert not unexecuted, f"cells {unexecuted} did not run"
    assert figure_cells(notebook) == figure_cells(committed)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_outputs_print_no_float_artefacts(path):
    """Numbers are formatted, not printed as binary floats' expansions (16.80000000000109)."""
    import re

    artefact = re.compile(r"\d\.\d*(0{6,}|9{6,})\d")
    for cell in nbformat.read(path, as_version=4).cells:
        for out in cell.get("outputs", []):
            text = out.get("text", "") + str(out.get("data", {}).get("text/plain", ""))
            assert not artefact.search(text), artefact.search(text).group()
