# Two commands on a fresh machine: `make demo` and `make test` (both idempotent).
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
PYTHON ?= python3

.PHONY: demo test quick setup llvm clean bench

setup: $(STAMP) llvm

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

# Dr.Jit 1.5's LLVM backend needs libLLVM >= 16 (14/15 abort the process).
llvm: $(STAMP)
	@bash tools/ensure_llvm.sh $(PY)

# rendered again only when the package (its code, the demo scene, the install) is newer
# than demo_out/summary.json (written last): a second `make demo` renders nothing
DEMO_INPUTS := $(STAMP) $(shell find src/dopplertof -name '*.py' -o -name '*.xml')

demo: setup demo_out/summary.json
	@echo "demo_out/ is up to date with the package (rm demo_out/summary.json to render it again)"

demo_out/summary.json: $(DEMO_INPUTS)
	$(VENV)/bin/dopplertof demo -o demo_out

# the whole suite (what CI runs, one process); `make quick`: the fast tier, for the
# edit-test loop, in two pytest-xdist processes (144 s on the idle 2-core machine,
# 2026-12-07; in one process about 1.4x that: docs/testing.md)
test: setup
	$(PY) -m pytest -q

quick: setup
	$(PY) -m pytest -q -m "not slow" -n 2

bench: setup
	$(PY) benchmarks/throughput.py
	$(PY) benchmarks/variance.py --quick

clean:
	rm -rf $(VENV) demo_out .pytest_cache
