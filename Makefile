# `make demo` runs the main job, `make test` the test suite (everything not marked slow; what CI
# runs), `make test-all` every test, `make docs` the API reference (docs/api/); each creates
# .venv when missing (`make test-oldest`: the quick suite on the oldest dependencies, in its
# own .venv-oldest). The tests run in two pytest-xdist workers: 4 min 37-44 s against 7 min
# in one process on 2 cores when last compared; pytest 2 to 5 min since (by machine); they share
# one scratch compilation cache (tests/conftest.py; benchmarks/RESULTS.md, "Test suite time").
# Each test file runs in one worker (--dist loadfile), so its tests share compiled programs:
# 4:00 against 4:21 spread test by test, and 4:33 against 4:44 with worksteal (one pair each).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OLDEST := .venv-oldest

.PHONY: demo test test-all test-slow test-oldest notebooks docs clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed-test: pyproject.toml | $(BIN)/activate
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.installed-notebooks: $(VENV)/.installed-test
	$(BIN)/python -m pip install --quiet -e '.[test,notebooks]'
	touch $@

demo: $(VENV)/.installed-test
	$(BIN)/jaxarm reproduce-paper --quick --out results
	@echo "Report: results/report.md"

test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not slow"

test-all: $(VENV)/.installed-notebooks
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

test-slow: $(VENV)/.installed-notebooks
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m slow

# The quick suite on the oldest dependency versions pyproject.toml admits, in a fresh
# .venv-oldest (tests/oldest-versions.txt).
test-oldest:
	rm -rf $(OLDEST)
	$(PYTHON) -m venv $(OLDEST)
	$(OLDEST)/bin/python -m pip install --quiet --upgrade pip
	$(OLDEST)/bin/python -m pip install --quiet -c tests/oldest-versions.txt -e '.[test]'
	$(OLDEST)/bin/python -m pytest -q -n 2 --dist loadfile -m "not slow"

notebooks: $(VENV)/.installed-notebooks
	$(BIN)/python notebooks/execute.py

docs: $(VENV)/.installed-test
	$(BIN)/python docs/build_api.py

clean:
	rm -rf $(VENV) $(OLDEST) results docs/api .pytest_cache .hypothesis
