# The README's two commands: `make demo` and `make test`. Each creates .venv if needed
# and installs the package into it, then fills numba's cache (python -m shapeverify.warmup);
# re-running is cheap (the install is redone only when pyproject.toml changes).
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,service,batch,scanners]"
	@# numba compiles the numeric kernels on first use; do it once here (and say so), so the
	@# first inspection answers in seconds (python -m shapeverify.warmup; see the README)
	$(BIN)/python -m shapeverify.warmup || echo "warm-up failed (see above): the kernels will compile on first use"
	@touch $(STAMP)

# `make demo OPTICS=1` adds the optical chain: fringe images -> points -> verdict
demo: $(STAMP)
	$(BIN)/python -m shapeverify.demo demo-output $(if $(OPTICS),--optics,)

test: $(STAMP)
	$(BIN)/python -m pytest -q

# benchmarks against named peers (installs the bench extra: Open3D, splipy, geomdl, pykdtree)
bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[dev,service,batch,scanners,bench]"
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done
	$(BIN)/python benchmarks/collect_results.py

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info
