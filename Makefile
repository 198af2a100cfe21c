# uwbwb — every target creates the environment it needs: .venv from environment.txt (the workbench: lab, class,
# reproduce), plus environment-test.txt for test and bench (pytest, the browser driver, Dask).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
# The numba kernels compiled into their cache, again whenever a package source changed (a pull that changes a kernel
# recompiles it here, not in a student's first run).
KERNELS := $(VENV)/.kernels-compiled
LAB_IP ?= 127.0.0.1
LAB_PORT ?= 8888
# JupyterLab refuses to start as root unless told; containers and CI machines often run as root.
LAB_ROOT := $(if $(filter 0,$(shell id -u)),--allow-root,)

.PHONY: lab test reproduce class times bench env clean

$(STAMP): environment.txt pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r environment.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m ipykernel install --sys-prefix --name python3 --display-name "Python 3 (uwbwb)" >/dev/null
	touch $(STAMP)

$(KERNELS): $(STAMP) $(shell find uwbwb -name '*.py')
	$(PY) -m uwbwb.filters.twins   # compile the numba kernels into their cache, not in a student's first run
	touch $(KERNELS)

$(TEST_STAMP): $(STAMP) environment-test.txt
	$(PY) -m pip install --quiet -r environment-test.txt
	touch $(TEST_STAMP)

env: $(KERNELS)

## Open the workbench: JupyterLab on notebooks/ (token auth on, loopback only by default).
## LAB_DIR=class/student opens the student copies that `make class` writes instead.
LAB_DIR ?= notebooks
lab: $(KERNELS)
	$(VENV)/bin/jupyter lab --notebook-dir=$(LAB_DIR) --ServerApp.ip=$(LAB_IP) --ServerApp.port=$(LAB_PORT) $(LAB_ROOT)

## Run the whole test suite, notebooks and the browser test included, on every core (TEST_WORKERS=0: one process);
## whole files to each worker, the files that execute notebooks first (tests/conftest.py).
TEST_WORKERS ?= auto
test: $(TEST_STAMP) $(KERNELS)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder $(PYTEST_ARGS)

## Headless main job: execute every notebook, write reports/ with summary.json + summary.md.
reproduce: $(KERNELS)
	$(PY) -m uwbwb reproduce $(REPRODUCE_ARGS)

## Class mode (CLASS=True, FAST=True), for a lecturer: class/student/ holds the notebooks to hand out (no outputs,
## CLASS = True in the parameters cell, research cells folded, the glossary beside them; `make lab
## LAB_DIR=class/student`), class/answers/ the same notebooks run from there, offline HTML handouts (no research
## cells), TEACHING.md and the glossary. Prints run times and class-limit violations (the times the docs quote: make times).
## CLASS_ARGS="--only 00 01 --kernel python3" picks notebooks and the kernel.
class: $(KERNELS)
	$(PY) -m uwbwb.classroom $(CLASS_ARGS)

## Measure each notebook's class-mode and FAST run time (one at a time) into docs/run_times.md, the one table the
## notebook fronts, README and TEACHING.md quote (TIMES_ARGS="--only 00 03", "--full" adds full fidelity: long).
times: $(KERNELS)
	$(PY) benchmarks/run_times.py $(TIMES_ARGS)

bench: $(TEST_STAMP) $(KERNELS)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) reports test-output .pytest_cache
