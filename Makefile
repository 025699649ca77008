# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test lint fmus docs docs-check clean

# The virtual environment with the project (editable) and, for tests, its test extras.
$(VENV)/.base: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	$(BIN)/python -m compileall -q analysis fmus build_fmus >/dev/null  # as pip does for a regular install
	touch $@

$(VENV)/.test: $(VENV)/.base
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.docs: $(VENV)/.base
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	touch $@

fmus: $(VENV)/.base
	$(BIN)/dfwb build

demo: fmus
	$(BIN)/dfwb demo --out out
	$(BIN)/dfwb paper --out out/paper

# One pytest-xdist worker per core (the FMUs are built once, under a lock, and shared), work stealing; the slowest
# 15 tests listed at the end of every run.
test: $(VENV)/.test
	$(BIN)/python -m pytest -q -n auto --dist worksteal --durations=15

# The documentation site (docs/_build/html/index.html), warnings as errors, the example notebooks executed.
docs: $(VENV)/.docs fmus
	$(BIN)/python -m sphinx -b html -W --keep-going -q docs docs/_build/html

# The same check for CI: every notebook executed afresh (no cached outputs), the hunting notebook on 3 x 3 maps
# instead of 12 x 12 (DFWB_HUNTING_N).
docs-check: $(VENV)/.docs fmus
	DFWB_HUNTING_N=3 $(BIN)/python -m sphinx -b html -W --keep-going -q -D nb_execution_mode=force docs $(or $(TMPDIR),/tmp)/dfwb-docs-check

# ruff, configured in pyproject.toml ([tool.ruff]); installed with the test extras.
lint: $(VENV)/.test
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build out docs/_build docs/examples docs/reference/generated
