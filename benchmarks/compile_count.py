"""How many programs the quick report compiles: the search's, the checks' and refine's jit caches.

Runs ``reproduce_paper(quick=True)`` in this process (into a scratch folder, no persistent
cache) and prints the number of compiled ``search`` programs, of check programs (``fitness``,
``violation`` and ``certify`` share them: one per problem spec and batch size) and of
``refine`` programs, and the wall time.

    JAXARM_CACHE_DIR=off .venv/bin/python benchmarks/compile_count.py
"""

from __future__ import annotations

import tempfile
import time

from jaxarm.model import problem
from jaxarm.optim import refine as refine_lib
from jaxarm.optim.restarts import compiled_search
from jaxarm.paper.report import reproduce_paper


def main():
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        reproduce_paper(out, quick=True)
    print(f"search programs {compiled_search._cache_size()}, check programs "
          f"{problem._evaluate_and_certify._cache_size()}, refine programs "
          f"{refine_lib._compiled_refine._cache_size()}, {time.perf_counter() - began:.0f} s")


if __name__ == "__main__":
    main()
