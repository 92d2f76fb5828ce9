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

demo: setup
	$(VENV)/bin/dopplertof demo -o demo_out

# the whole suite (what CI runs); `make quick`: the fast tier, for the edit-test loop
test: setup
	$(PY) -m pytest -q

quick: setup
	$(PY) -m pytest -q -m "not slow"

bench: setup
	$(PY) benchmarks/throughput.py
	$(PY) benchmarks/variance.py --quick

clean:
	rm -rf $(VENV) demo_out .pytest_cache
