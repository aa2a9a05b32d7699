# Two commands do everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup demo test test-full reproduce build bench clean native-deps browser-deps

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,nastran]'
	$(PY) -m pip install -q --no-deps 'pyNastran==1.4.1'  # declares numpy<2; see pyproject
	@{ command -v x86_64-w64-mingw32-gcc && command -v wine; } >/dev/null 2>&1 \
	  || $(MAKE) --no-print-directory native-deps \
	  || echo "note: no mingw-w64 cross compiler or wine (needs root and apt-get): native FMUs get no win64 binaries, or the same-bits tests cannot run them, and those tests say so"
	@command -v chromium >/dev/null 2>&1 || $(MAKE) --no-print-directory browser-deps \
	  || echo "note: no chromium (needs root and apt-get): the report's browser test skips and says so"
	touch $(STAMP)

# The win64 binaries of the native FMUs need the mingw-w64 cross compiler (Debian package,
# root needed); `make setup` runs this when the compiler or wine is missing.  Without it the
# native FMUs carry linux64 binaries and sources only.  wine runs the win64 builds in
# the tests (tests/nativefmu/test_jfmath.py: the same bits as linux64).
native-deps:
	apt-get install -y -q gcc-mingw-w64-x86-64 wine wine64 \
	  || { apt-get update -q && apt-get install -y -q gcc-mingw-w64-x86-64 wine wine64; }

# The report is checked in a real browser (tests/orchestrator/browser.py): headless
# Chromium, a Debian package (root needed); `make setup` runs this when it is missing.
browser-deps:
	apt-get install -y -q chromium \
	  || { apt-get update -q && apt-get install -y -q chromium; }

demo: setup
	$(VENV)/bin/jitterfmu reproduce truss-frf --out out/demo
	$(VENV)/bin/jitterfmu reproduce truss-decay --out out/demo
	$(VENV)/bin/jitterfmu reproduce eos-budget --out out/demo --workers 2
	$(VENV)/bin/jitterfmu report out/demo/eos-budget-campaign

# Two workers (a file's tests share one); the 15 slowest tests are listed at the end.
test: setup
	$(PY) -m pytest -q -n 2 --dist loadfile -m "not paper and not long" --durations=15

# What must run long: the paper's experiments and their designs at length (marker
# `paper`) and the tests measured at 6 s or more in `make test` on a fresh clone (marker
# `long`), so that `make test` stays within 300 s; CI runs both targets.
test-full: setup
	$(PY) -m pytest -q -n 2 --dist loadfile -m "paper or long" --durations=15

build: setup
	$(VENV)/bin/jitterfmu build

# The paper's experiments at full length (the tests run them with --quick), and two
# studies of the testbed: its stacks' servo loops and its gains' robust factors.
EXPERIMENTS := truss-frf truss-decay testbed-isolation swir-isolation eos-budget \
               testbed-servo testbed-robust
reproduce: setup
	for e in $(EXPERIMENTS); do $(VENV)/bin/jitterfmu reproduce $$e --out out/reproduce || exit 1; done
	$(VENV)/bin/jitterfmu reproduce testbed-isolation --variant hybrid --out out/reproduce/hybrid
	$(VENV)/bin/jitterfmu reproduce swir-isolation --variant central --out out/reproduce/central

bench: setup
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf out build
