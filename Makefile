# The two commands of the README quick start. Each sets up what it needs on first use.
#   make reproduce   -> every version's battery and sensor tables and figures, in results/<version>/
#                       (base install: no torch)
#   make test        -> system packages, full install, lint, format and type checks, schema check,
#                       the test suite, leaderboard verify (what .ci/run runs)
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
PIP := $(BIN)/pip install --quiet --disable-pip-version-check
SOURCES := scftc_cli tests benchmarks examples

# command:Debian package pairs the test suite needs (sandbox, seccomp, browser test).
SYSTEM_PACKAGES := bwrap:bubblewrap libseccomp.so.2:libseccomp2 chromium:chromium chromedriver:chromium-driver

.PHONY: setup setup-dev sysdeps reproduce test lint bench

setup: $(VENV)/.installed-base

setup-dev: sysdeps $(VENV)/.installed-dev

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# The package and its run-time dependencies: enough to evaluate every controller and reproduce the study.
$(VENV)/.installed-base: pyproject.toml | $(VENV)/bin/python
	$(PIP) -e .
	touch $@

# Everything: torch==2.13.0 first (a looser torch requirement could pull a multi-GB CUDA build),
# then training, RL, Basilisk, Dask and the developer tools.
$(VENV)/.installed-dev: pyproject.toml | $(VENV)/bin/python
	$(PIP) torch==2.13.0
	$(PIP) -e '.[dev,learn,rl,basilisk,dask]'
	touch $(VENV)/.installed-base $@

# Installs the missing Debian packages when run as root; otherwise names the command to run.
sysdeps:
	@missing=""; \
	for pair in $(SYSTEM_PACKAGES); do \
	  probe=$${pair%%:*}; package=$${pair#*:}; \
	  case $$probe in \
	    *.so*) /sbin/ldconfig -p 2>/dev/null | grep -q "$$probe" || missing="$$missing $$package";; \
	    *) command -v $$probe >/dev/null 2>&1 || missing="$$missing $$package";; \
	  esac; \
	done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing system packages:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	  else \
	    echo "error: missing system packages:$$missing; install them with: sudo apt-get install -y$$missing" >&2; \
	    exit 1; \
	  fi; \
	fi

# Every registered benchmark version (scftc_cli/versions), the default first.
VERSIONS = $$($(BIN)/python -c 'from scftc_cli.versions import version_names; print(*version_names())')

reproduce: setup
	for version in $(VERSIONS); do $(BIN)/scftc reproduce --benchmark $$version || exit 1; done

test: setup-dev
	$(BIN)/ruff check $(SOURCES)
	$(BIN)/ruff format --check $(SOURCES)
	$(BIN)/mypy
	$(BIN)/scftc schemas --check
	SCFTC_FORBID_SKIPS=1 $(BIN)/pytest -q
	for version in $(VERSIONS); do $(BIN)/scftc leaderboard verify --benchmark $$version || exit 1; done

lint: setup-dev
	$(BIN)/ruff check $(SOURCES)
	$(BIN)/ruff format --check $(SOURCES)
	$(BIN)/mypy

bench: setup-dev
	$(BIN)/python benchmarks/throughput.py
