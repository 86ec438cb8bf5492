# The two commands of the README quick start. Each sets up .venv on first use.
#   make reproduce   -> the study's battery and sensor tables and figures, in results/
#   make test        -> lint, format and type checks, schema check, the test suite, leaderboard verify
#                       (what .ci/run runs)
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup reproduce test lint bench

setup: $(VENV)/.installed

# torch==2.13.0 first: a looser torch requirement could pull a multi-GB CUDA build.
$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --disable-pip-version-check torch==2.13.0
	$(BIN)/pip install --quiet --disable-pip-version-check -e '.[dev,basilisk,rl]'
	touch $@

reproduce: setup
	$(BIN)/scftc reproduce --out results/

test: setup
	$(BIN)/ruff check scftc_cli tests benchmarks
	$(BIN)/ruff format --check scftc_cli tests benchmarks
	$(BIN)/mypy
	$(BIN)/scftc schemas --check
	$(BIN)/pytest -q
	$(BIN)/scftc leaderboard verify

lint: setup
	$(BIN)/ruff check scftc_cli tests benchmarks
	$(BIN)/ruff format --check scftc_cli tests benchmarks
	$(BIN)/mypy

bench: setup
	$(BIN)/python benchmarks/throughput.py
