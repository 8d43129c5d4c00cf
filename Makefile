# Everything a fresh machine needs, from Python 3.11 and the package registry.
# Each target installs only what it needs, with its own stamp file: `make render` installs
# the package alone, `make test` adds the dev extras, `make bench` the bench extras too.
PYTHON ?= python3.11
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP_RENDER := $(VENV)/.installed-render
STAMP_DEV    := $(VENV)/.installed-dev
STAMP_BENCH  := $(VENV)/.installed-bench
STAMP_DOCS   := $(VENV)/.installed-docs

.PHONY: render test lint bench docs gallery wheel clean

$(BIN)/python:
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "need $(PYTHON) on PATH (or: make PYTHON=python3 ...)"; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# An editable install leaves the package's bytecode to its first import (pip compiles a wheel's
# at install): compiled here, the first render does not spend ~0.35 s on it.
$(STAMP_RENDER): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	$(BIN)/python -m compileall -q src
	@touch $@

$(STAMP_DEV): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	$(BIN)/python -m compileall -q src
	@touch $@ $(STAMP_RENDER)

$(STAMP_BENCH): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev,bench]'
	$(BIN)/python -m compileall -q src
	@touch $@ $(STAMP_DEV) $(STAMP_RENDER)

$(STAMP_DOCS): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	$(BIN)/python -m compileall -q src
	@touch $@ $(STAMP_RENDER)

## render: render the built-in seed scene to render.png
render: $(STAMP_RENDER)
	$(BIN)/raylume render

## test: run the full test suite
test: $(STAMP_DEV)
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup

## lint: ruff's lint rules and formatting (configured in pyproject.toml)
lint: $(STAMP_DEV)
	$(BIN)/ruff check src tests benchmarks tools
	$(BIN)/ruff format --check src tests benchmarks tools

## bench: print the benchmark tables (see benchmarks/README.md)
# Debian's libllvm19 serves Mitsuba's llvm_ad_rgb variant (an older libLLVM fails to compile its
# kernels), chromium and its driver bench_view.py, valgrind count_instructions.py; where apt-get
# cannot install them, those skip.
bench: $(STAMP_BENCH)
	bash tools/apt_install.sh libllvm19 chromium chromium-driver valgrind
	$(BIN)/python benchmarks/run_all.py

## docs: build the documentation site into site/; any warning fails (mkdocs.yml: strict)
# The two variables silence banners that MkDocs' plugins print about MkDocs 2.0 (the docs extra pins 1.x).
docs: $(STAMP_DOCS)
	NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true $(BIN)/python -m mkdocs build --strict --site-dir site

## gallery: render every picture the documentation shows, from the commands its gallery page prints (the
## denoised ones need pyoidn, a dev extra)
gallery: $(STAMP_DEV)
	$(BIN)/python tools/gallery.py

## wheel: build the sdist and wheel into dist/ and check the wheel installed alone (tools/check_wheel.py)
wheel: $(STAMP_DEV)
	rm -rf dist
	$(BIN)/python -m build --outdir dist .
	$(BIN)/python tools/check_wheel.py dist/raylume-*.whl

clean:
	rm -rf $(VENV) render.png .pytest_cache site build dist
