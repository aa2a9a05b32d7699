# Two commands do everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup demo test reproduce build bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $(STAMP)

demo: setup
	$(VENV)/bin/jitterfmu reproduce truss-frf --out out/demo
	$(VENV)/bin/jitterfmu reproduce truss-decay --out out/demo
	$(PY) -W ignore -m orchestrator.experiments.eos_budget --out out/demo/eos_budget --workers 2
	$(VENV)/bin/jitterfmu report out/demo/eos_budget/eos-budget-campaign

test: setup
	$(PY) -m pytest -q

clean:
	rm -rf out build
