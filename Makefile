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
# pip installs uv into the venv, and uv installs the rest, compiled to bytecode as pip does:
# 18-19 s against pip's 41-44 s for the test install on 2 cores (benchmarks/RESULTS.md, "uv
# installs the suite's dependencies"). pip installs them where uv cannot (no uv wheel for the
# platform, or an index that only pip is configured to reach).
install = $(1)/bin/uv pip install --quiet --compile-bytecode --python $(1)/bin/python $(2) \
	|| $(1)/bin/python -m pip install --quiet $(2)
TEST_EXTRAS := .[test]
NOTEBOOK_EXTRAS := .[test,notebooks]

.PHONY: demo test test-all test-slow test-oldest notebooks docs clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)

$(BIN)/uv: | $(BIN)/activate
	$(BIN)/python -m pip install --quiet uv || echo "uv not installed: pip installs the rest"

$(VENV)/.installed-test: pyproject.toml | $(BIN)/uv
	$(call install,$(VENV),-e '$(TEST_EXTRAS)')
	touch $@

$(VENV)/.installed-notebooks: $(VENV)/.installed-test
	$(call install,$(VENV),-e '$(NOTEBOOK_EXTRAS)')
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
	$(OLDEST)/bin/python -m pip install --quiet uv || echo "uv not installed: pip installs the rest"
	$(call install,$(OLDEST),-c tests/oldest-versions.txt -e '$(TEST_EXTRAS)')
	$(OLDEST)/bin/python -m pytest -q -n 2 --dist loadfile -m "not slow"

notebooks: $(VENV)/.installed-notebooks
	$(BIN)/python notebooks/execute.py

docs: $(VENV)/.installed-test
	$(BIN)/python docs/build_api.py

clean:
	rm -rf $(VENV) $(OLDEST) results docs/api .pytest_cache .hypothesis
