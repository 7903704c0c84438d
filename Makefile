# The README's commands: `make demo`, `make test`, `make test-fast`.  Each creates .venv if needed
# and installs the package into it, then fills numba's cache (python -m shapeverify.warmup);
# re-running is cheap (the install is redone only when pyproject.toml changes).  Every step says
# what it installs, and how big and long it is, before it starts.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# the warm-up's snapshot of numba's cache (python -m shapeverify.warmup --snapshot)
SNAPSHOT := $(abspath $(VENV))/warmup-snapshot
# pytest-xdist workers for `make test` / `make test-fast` (auto: one per core)
WORKERS ?= auto

.PHONY: demo test test-fast browser bench clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || { echo "== creating $(VENV) with $(PYTHON)"; $(PYTHON) -m venv $(VENV); }
	@echo "== installing shapeverify with its dev, service, batch and scanners extras into $(VENV) from PyPI"
	@echo "   (numpy, scipy, numba, OpenCASCADE's cadquery-ocp-novtk, matplotlib, plotly, Dask,"
	@echo "   FastAPI, pytest, ...: about 1 GB, 2-5 minutes; pip's own output is kept quiet)"
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,service,batch,scanners]"
	@# numba compiles the numeric kernels on first use; do it once here (and say so), so the
	@# first inspection answers in seconds (python -m shapeverify.warmup; see the README).
	@# --snapshot: a copy of what it wrote to an empty cache (none if the cache held entries),
	@# taken before any test adds to the cache: tests/test_warmup_coverage.py runs its commands
	@# on a copy of it instead of compiling everything again (216 s of a fresh clone's suite)
	$(BIN)/python -m shapeverify.warmup --snapshot $(SNAPSHOT) || echo "warm-up failed (see above): the kernels will compile on first use"
	@touch $(STAMP)

# `make demo OPTICS=1` adds the optical chain: fringe images -> points -> verdict
demo: $(STAMP)
	$(BIN)/python -m shapeverify.demo demo-output $(if $(OPTICS),--optics,)

# the whole suite (slow tests included), after `make browser` (Chromium for the HTML report's
# browser test, or a note that it will be skipped).  pytest-xdist runs one worker per core
# (WORKERS=0 runs it in this one process); each test file stays on one worker (--dist loadfile), so
# a file's module fixtures (a NIST part imported and prepared) are built once.  Files go out in
# collection order (--no-loadscope-reorder; xdist's default hands out the files with the most
# tests first), which conftest.py starts with the longest files (LONG_FILES), so the run does
# not end on one worker finishing a long NIST file alone
# PYTHONDONTWRITEBYTECODE= : pytest keeps the assertion-rewritten test modules in __pycache__
# only when Python may write bytecode; with PYTHONDONTWRITEBYTECODE=1 in the environment (as on
# the test machines) every worker rewrote all ~460 test modules at every run (collection: 15.8 s
# of CPU per worker, 7.5 s with the cache)
# --durations=40: the run ends with its 40 slowest tests, so every log (CI's too) says where the
# suite's time went
test: $(STAMP) browser
	PYTHONDONTWRITEBYTECODE= SHAPEVERIFY_WARMUP_SNAPSHOT=$(SNAPSHOT) $(BIN)/python -m pytest -q -n $(WORKERS) --dist loadfile --no-loadscope-reorder --durations=40

# the quick tests only: no test marked slow, no browser, no real data (README: how long)
test-fast: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q -n $(WORKERS) --dist loadfile --no-loadscope-reorder -m "not slow and not shared"

# The browser test of the HTML report (tests/test_report_browser.py) runs headless Chromium, and
# only Chromium (Debian package `chromium`, without its recommended packages: 25 packages, about
# 115 MB to download, 400 MB on disk, upgrades nothing).  Installed here, saying so first, when
# it is missing and this is root with apt-get; SKIP_BROWSER=1 or no root/apt-get: nothing is
# installed and the test is skipped with the reason (so it is when apt-get fails or is offline).
browser:
	@if command -v chromium >/dev/null 2>&1; then \
	  echo "== Chromium for the browser test: $$(command -v chromium)"; \
	elif [ -n "$(SKIP_BROWSER)" ]; then \
	  echo "== SKIP_BROWSER set: Chromium is not installed; the browser test will be skipped"; \
	elif [ "$$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then \
	  echo "== Chromium is missing (Debian package chromium) and installing it needs root and apt-get:"; \
	  echo "   the browser test of the HTML report will be skipped (install chromium to run it)"; \
	else \
	  echo "== installing Chromium for the browser test of the HTML report (SKIP_BROWSER=1 skips):"; \
	  echo "   apt-get install --no-install-recommends --no-upgrade chromium: 25 Debian packages,"; \
	  echo "   about 115 MB to download, 400 MB on disk, about 1 minute; nothing else is upgraded"; \
	  { DEBIAN_FRONTEND=noninteractive apt-get update -q >/dev/null && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends --no-upgrade chromium; } \
	  || echo "== installing Chromium failed (offline or refused): the browser test will be skipped"; \
	fi

# benchmarks against named peers (installs the bench extra: Open3D, splipy, geomdl, pykdtree)
bench: $(STAMP)
	@echo "== installing the bench extra (Open3D, splipy, geomdl, pykdtree, trimesh, ...: about 600 MB)"
	$(BIN)/python -m pip install --quiet -e ".[dev,service,batch,scanners,bench]"
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done
	$(BIN)/python benchmarks/collect_results.py

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info
