# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test lint fmus clean

# The virtual environment with the project (editable) and, for tests, its test extras.
$(VENV)/.base: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.test: $(VENV)/.base
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

fmus: $(VENV)/.base
	$(BIN)/dfwb build

demo: fmus
	$(BIN)/dfwb demo --out out
	$(BIN)/dfwb paper --out out/paper

test: $(VENV)/.test
	$(BIN)/python -m pytest -q

# ruff, configured in pyproject.toml ([tool.ruff]); installed with the test extras.
lint: $(VENV)/.test
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build out
