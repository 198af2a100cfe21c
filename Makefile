# uwbwb — every target creates the environment it needs (.venv from environment.txt).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
LAB_IP ?= 127.0.0.1
LAB_PORT ?= 8888
# JupyterLab refuses to start as root unless told; containers and CI machines often run as root.
LAB_ROOT := $(if $(filter 0,$(shell id -u)),--allow-root,)

.PHONY: lab test reproduce class bench env clean

$(STAMP): environment.txt pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r environment.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m ipykernel install --sys-prefix --name python3 --display-name "Python 3 (uwbwb)" >/dev/null
	touch $(STAMP)

env: $(STAMP)

## Open the workbench: JupyterLab on notebooks/ (token auth on, loopback only by default).
lab: $(STAMP)
	$(VENV)/bin/jupyter lab --notebook-dir=notebooks --ServerApp.ip=$(LAB_IP) --ServerApp.port=$(LAB_PORT) $(LAB_ROOT)

## Run the whole test suite, notebooks and the browser test included, on every core (TEST_WORKERS=0: one process).
TEST_WORKERS ?= auto
test: $(STAMP)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

## Headless main job: execute every notebook, write reports/ with summary.json + summary.md.
reproduce: $(STAMP)
	$(PY) -m uwbwb reproduce $(REPRODUCE_ARGS)

## Class mode: every notebook with CLASS=True and FAST=True into class/: executed notebooks with the research
## cells folded, HTML handouts without them; prints run times and class-limit violations.
## CLASS_ARGS="--only 00 01 --kernel python3" picks notebooks and the kernel.
class: $(STAMP)
	$(PY) -m uwbwb.classroom $(CLASS_ARGS)

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) reports test-output .pytest_cache
