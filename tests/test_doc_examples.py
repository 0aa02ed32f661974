"""The ``>>>`` examples of the README and the user guide print what the pages say they print.

Sample output in the docs comes from running it: each page's ```pycon blocks run as one
doctest (``...`` stands for what may differ between machines).
"""

import doctest
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).parents[1]
PAGES = [ROOT / "README.md", ROOT / "docs" / "index.md",
         *sorted((ROOT / "docs" / "guide").glob("*.md"))]


def pycon_blocks(page: pathlib.Path) -> str:
    return "\n".join(re.findall(r"^```pycon\n(.*?)^```$", page.read_text(), flags=re.S | re.M))


@pytest.mark.parametrize("page", [p for p in PAGES if pycon_blocks(p)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_page_examples_print_what_the_page_shows(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    test = doctest.DocTestParser().get_doctest(pycon_blocks(page), {}, page.name, str(page), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    failed, attempted = runner.summarize(verbose=False)
    assert attempted > 0 and failed == 0, f"{failed} of {attempted} examples in {page.name}"


def test_a_stale_sample_output_fails(tmp_path):
    """The check itself: an example whose shown output is wrong is caught."""
    page = tmp_path / "page.md"
    page.write_text("```pycon\n>>> 1 + 1\n3\n\n```\n")
    test = doctest.DocTestParser().get_doctest(pycon_blocks(page), {}, "page", str(page), 0)
    runner = doctest.DocTestRunner()
    runner.run(test, out=lambda text: None)
    assert runner.summarize(verbose=False).failed == 1
