# Everything a fresh machine needs, from Python 3.11 and the package registry.
PYTHON ?= python3.11
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: render test bench clean

$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "need $(PYTHON) on PATH (or: make PYTHON=python3 ...)"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,bench]'
	@touch $(STAMP)

## render: render the built-in seed scene to render.png
render: $(STAMP)
	$(BIN)/raylume render

## test: run the full test suite
test: $(STAMP)
	$(BIN)/python -m pytest -q

## bench: print the benchmark tables (see benchmarks/README.md)
bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) render.png .pytest_cache
