# `make demo` runs the main job, `make test` the test suite (everything not marked slow: what CI
# runs) and a strict build of the user guide, `make test-all` every test, `make docs` the user
# guide and API reference (mkdocs, into site/); each creates .venv when missing
# (`make test-oldest`: the quick suite on the oldest dependencies, in its own .venv-oldest).
# The tests run in two pytest-xdist workers, each test file in one worker (--dist loadfile) so
# that its tests share compiled programs; they share one scratch compilation cache
# (tests/conftest.py). Why these choices: benchmarks/RESULTS.md, "Decisions and negative results".
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OLDEST := .venv-oldest
# uv installs the dependencies (and pip, for the user), compiled to bytecode as pip does; pip
# installs them where uv cannot (no uv wheel for the platform, or an index that only pip is
# configured to reach).
install = $(1)/bin/uv pip install --quiet --compile-bytecode --python $(1)/bin/python pip $(2) \
	|| ($(call pip_into,$(1)) && $(1)/bin/python -m pip install --quiet $(2))
# The venvs are made without pip (faster) and the interpreter's pip installs uv into them
# (pip >= 22.3: `--python`). Where that fails, the venv gets its bundled pip (`ensurepip`),
# which installs uv, or all.
pip_into = $(1)/bin/python -m pip --version >/dev/null 2>&1 \
	|| $(1)/bin/python -m ensurepip --default-pip >/dev/null
uv_into = $(PYTHON) -m pip --python $(1)/bin/python install --quiet uv 2>/dev/null \
	|| ($(call pip_into,$(1)) && $(1)/bin/python -m pip install --quiet uv) \
	|| echo "uv not installed: pip installs the rest"
TEST_EXTRAS := .[test]
NOTEBOOK_EXTRAS := .[test,notebooks]

.PHONY: demo test test-all test-slow test-oldest notebooks docs clean

$(BIN)/activate:
	$(PYTHON) -m venv --without-pip $(VENV)

$(BIN)/uv: | $(BIN)/activate
	$(call uv_into,$(VENV))

# The demo needs jaxarm's own dependencies only; the tests add theirs (the user guide's build
# among them).
$(VENV)/.installed: pyproject.toml | $(BIN)/uv
	$(call install,$(VENV),-e .)
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/uv
	$(call install,$(VENV),-e '$(TEST_EXTRAS)')
	touch $@

$(VENV)/.installed-notebooks: $(VENV)/.installed-test
	$(call install,$(VENV),-e '$(NOTEBOOK_EXTRAS)')
	touch $@

demo: $(VENV)/.installed
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
	$(PYTHON) -m venv --without-pip $(OLDEST)
	$(call uv_into,$(OLDEST))
	$(call install,$(OLDEST),-c tests/oldest-versions.txt -e '$(TEST_EXTRAS)')
	$(OLDEST)/bin/python -m pytest -q -n 2 --dist loadfile -m "not slow"

notebooks: $(VENV)/.installed-notebooks
	$(BIN)/python notebooks/execute.py

docs: $(VENV)/.installed-test
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict
	@echo "User guide: site/index.html"

clean:
	rm -rf $(VENV) $(OLDEST) results site .cache .pytest_cache .hypothesis
