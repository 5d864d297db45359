# skidsim: the two commands of the README are `make reproduce` and `make test`.
# Both create (or reuse) a local virtual environment in .venv with the pinned dependencies.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
CORES ?= 2
STAMP := $(VENV)/.skidsim-installed
TEST_STAMP := $(VENV)/.skidsim-test-installed

.PHONY: reproduce test test-campaigns lint setup setup-test system-deps report dryrun clean-results benchmarks test-slurm

# Installer: uv (pinned, itself installed by pip) installs the locked wheels in parallel, 15 s against pip's 31 s
# with byte-compilation (2026-11-29, docs/performance.md); where uv cannot (no wheel for the platform, no index it
# reaches), pip installs the same pins. UV_PIP is the command line of either.
UV_VERSION := 0.13.9
INSTALL = $(BIN)/python -m pip install -q uv==$(UV_VERSION) >/dev/null 2>&1 && $(BIN)/uv --version >/dev/null 2>&1 \
	&& UV_PIP="$(BIN)/uv pip install -q --compile-bytecode --python $(BIN)/python" \
	|| { $(BIN)/python -m pip install -q --upgrade pip; UV_PIP="$(BIN)/python -m pip install -q"; }

$(STAMP): requirements.lock pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(INSTALL); set -e; echo "installer: $$UV_PIP"; \
	  $$UV_PIP -r requirements.lock || { echo "uv failed: pip"; $(BIN)/python -m pip install -q -r requirements.lock; }; \
	  $$UV_PIP --no-deps -e . || $(BIN)/python -m pip install -q --no-deps -e .
	@# byte-compile the package now: where PYTHONDONTWRITEBYTECODE is set (as on this workplace's machines) every job
	@# would compile the modules it imports again (up to 0.1 s of CPU per job; a default run has 457 jobs)
	$(BIN)/python -m compileall -q src
	@touch $@

$(TEST_STAMP): $(STAMP) requirements-test.lock requirements-test-nodeps.lock
	$(INSTALL); set -e; \
	  $$UV_PIP -r requirements-test.lock || $(BIN)/python -m pip install -q -r requirements-test.lock; \
	  $$UV_PIP --no-deps -r requirements-test-nodeps.lock || $(BIN)/python -m pip install -q --no-deps -r requirements-test-nodeps.lock
	@touch $@

setup: $(STAMP)

setup-test: $(TEST_STAMP) system-deps

# CalculiX (Debian package calculix-ccx) is the independent FE code the solver is compared with.
system-deps:
	@if command -v ccx >/dev/null 2>&1; then echo "ccx: $$(command -v ccx)"; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing calculix-ccx (Debian)"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq calculix-ccx >/dev/null) || echo "WARNING: could not install calculix-ccx"; \
	else echo "NOTE: CalculiX (ccx) not found and not root: the CalculiX comparison tests will be skipped. Install calculix-ccx."; fi

## Run the whole workflow on the embedded default campaign (or CONFIG=... for another config file).
## Stopped (Ctrl-C, kill -9)? Run it again: it resumes (skidsim.launch: stale lock removed, half-done jobs redone,
## finished FE runs kept).
reproduce: $(STAMP)
	$(BIN)/python -m skidsim.launch --cores $(CORES) $(if $(CONFIG),--configfile $(CONFIG),)

## Run the test suite (every test but the hidden-effect campaigns through the whole workflow: make test-campaigns).
test: setup-test
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile -q -m "not campaign" $(PYTEST_ARGS)

## The hidden-effect campaigns through the whole workflow with the real FE (tests marked campaign, minutes each);
## CI (.ci/run) runs them after make test.
test-campaigns: setup-test
	$(BIN)/python -m pytest -n $(CORES) --dist load -q -m campaign $(PYTEST_ARGS)

## Lint and format check (ruff, snakefmt; pinned in requirements-test.lock, configured in pyproject.toml). Fix with
## `$(BIN)/ruff check --fix . && $(BIN)/ruff format . && $(BIN)/snakefmt Snakefile workflow/rules/*.smk`.
lint: $(TEST_STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/snakefmt --check Snakefile workflow/rules/*.smk

## Run tests/test_slurm.py on this machine made a single-node SLURM cluster (cluster/single-node-slurm.sh, needs
## root), without and then with accounting (slurmdbd); both modes run even when the first fails, and a cluster this
## target started is stopped when it ends: after a failure and after Ctrl-C too (trap on EXIT).
## Measured figures (wall time, what SLURM granted each job) are appended to SLURM_REPORT.
SLURM_REPORT ?= benchmarks/out/slurm-report.jsonl
SLURM_CLUSTER ?= cluster/single-node-slurm.sh
test-slurm: setup-test
	@mkdir -p $(dir $(SLURM_REPORT)); \
	if ! $(SLURM_CLUSTER) status >/dev/null 2>&1; then \
	  trap '$(SLURM_CLUSTER) stop' EXIT; trap 'exit 130' INT; trap 'exit 143' TERM; \
	fi; \
	rc=0; for acct in 0 1; do \
	  if ! $(SLURM_CLUSTER) start $$([ $$acct = 1 ] && echo --accounting); then rc=1; break; fi; \
	  SKIDSIM_TEST_SLURM=1 SKIDSIM_SLURM_ACCOUNTING=$$acct SKIDSIM_SLURM_REPORT=$(abspath $(SLURM_REPORT)) \
	    $(BIN)/python -m pytest -p no:xdist -q -s tests/test_slurm.py $(PYTEST_ARGS) || rc=$$?; \
	done; exit $$rc

dryrun: $(STAMP)
	$(BIN)/snakemake -n --cores $(CORES)

report: $(STAMP)
	$(BIN)/snakemake --cores $(CORES) --report report.html

benchmarks: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean-results:
	rm -rf results logs benchmarks/out
