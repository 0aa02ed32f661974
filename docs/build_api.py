"""Build the API reference from the docstrings with pdoc (``make docs``; output ``docs/api/``).

Any warning pdoc raises (a broken reference, an annotation it cannot resolve) fails the build:
``tests/test_docs.py`` runs it in the test suite, so CI checks it.

Usage: ``python docs/build_api.py [OUTPUT_FOLDER]``.
"""

import pathlib
import sys
import typing
import warnings

import pdoc

import jaxarm
import jaxarm.plot  # imported here, not under pdoc: matplotlib's font scan runs a subprocess
from jaxarm._compile import stored_programs

MODULES = ["jaxarm", "jaxarm.plot", "jaxarm._compile.stored_programs"]
HERE = pathlib.Path(__file__).parent


def _resolve_namedtuple_annotations() -> None:
    """Give NamedTuples' generated ``__new__`` their fields' resolved types.

    Under ``from __future__ import annotations`` the generated ``__new__`` keeps the fields'
    annotations as strings that pdoc evaluates in the wrong namespace and warns about
    (mitmproxy/pdoc#765); ``typing.get_type_hints`` resolves them in the class's own module.
    """
    classes = [getattr(jaxarm, name) for name in jaxarm.__all__] + list(vars(stored_programs).values())
    for cls in classes:
        if isinstance(cls, type) and issubclass(cls, tuple) and hasattr(cls, "_fields"):
            hints = typing.get_type_hints(cls)
            cls.__new__.__annotations__ = {field: hints[field] for field in cls._fields}


def build(out: pathlib.Path) -> list[str]:
    """Write the HTML reference into ``out``; return pdoc's warnings (empty when clean)."""
    _resolve_namedtuple_annotations()
    pdoc.render.configure(docformat="google", footer_text=f"jaxarm {jaxarm.__version__}",
                          search=True, show_source=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*MODULES, output_directory=out)
    return [str(w.message) for w in caught]


if __name__ == "__main__":
    target = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "api"
    problems = build(target)
    for message in problems:
        print(f"docs warning: {message}", file=sys.stderr)
    if problems:
        sys.exit(1)
    print(f"API reference: {target / 'index.html'}")
