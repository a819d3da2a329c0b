# Fresh machine: `make run` (sets up, runs the main job) and `make test` (sets up, runs the tests).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# make test's pytest workers (pytest-xdist): the tests wait on processes much of the time
TEST_WORKERS ?= 2
STAMP  := $(VENV)/.installed

.PHONY: setup run test test-core bench clean

setup: $(STAMP)

# idempotent: rebuilt only when the package metadata changes
$(STAMP): setup.py setup.cfg package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade "pip>=24"
	$(PY) -m pip install --quiet -e ".[ros,figures,live,sweep,fast,test]"
	touch $(STAMP)

# RUN_ARGS: more options for the run, e.g. make run RUN_ARGS="--duration 1" (a shorter run)
run: setup
	$(VENV)/bin/predictive-drive run im_paper --strategy db_mptc $(RUN_ARGS)

test: setup
	$(VENV)/bin/ruff check src test examples
	$(VENV)/bin/ruff format --check src test examples
	$(VENV)/bin/mypy --strict src/predictive_drive
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile test

# the fast tier alone: no ROS, no node processes
test-core: setup
	$(PY) -m pytest -q -m core test

bench: setup
	$(VENV)/bin/predictive-drive bench

clean:
	rm -rf $(VENV) build install log
