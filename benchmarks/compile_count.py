"""How many programs the quick report makes: the search's, the checks' and refine's.

Runs ``reproduce_paper(quick=True)`` in this process (into a scratch folder, no persistent
cache) and prints the number of compiled ``search`` programs, of check programs (``fitness``,
``violation`` and ``certify`` share them: one per problem spec and batch size) and of
``refine`` programs, and the wall time.

    JAXARM_CACHE_DIR=off .venv/bin/python benchmarks/compile_count.py
"""

from __future__ import annotations

import tempfile
import time

from jaxarm.checks import evaluate
from jaxarm.optim import refine as refine_lib
from jaxarm.optim.restarts import compiled_search
from jaxarm.paper.report import reproduce_paper


def main():
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        reproduce_paper(out, quick=True)
    print(f"search programs {compiled_search.programs_made()}, check programs "
          f"{evaluate._evaluate_and_certify.programs_made()}, refine programs "
          f"{refine_lib._compiled_refine.programs_made()}, {time.perf_counter() - began:.0f} s")


if __name__ == "__main__":
    main()
