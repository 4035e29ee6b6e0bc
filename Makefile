# Two commands on a clean machine: `make run` and `make test`.
# Both create (or reuse) .venv from the pinned requirements.txt and install this package
# into it in editable mode; the stamp .venv/.installed is redone when the inputs change.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: venv run test clean

venv: $(STAMP)

$(STAMP): requirements.txt setup.py setup.cfg package.xml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -r requirements.txt
	$(BIN)/python -m pip install --no-deps -e .
	touch $@

run: $(STAMP)
	$(BIN)/rigid-body-sim run

test: export ROS_AUTOMATIC_DISCOVERY_RANGE = LOCALHOST
test: $(STAMP)
	$(BIN)/python -m pytest test -q -n 2 --dist loadgroup $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build install log .pytest_cache *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
