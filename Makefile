# Two entry points (see README): `make sim` and `make test`.
PY ?= python3
# test processes (pytest-xdist): most of the suite's time is real-time tests
# waiting, so two run side by side even on CI's 2 cores; a test file stays in
# one process (its module fixtures, often a whole simulated mission, run once)
TEST_JOBS ?= 2
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup sim test lint bench lock
$(BIN)/zarco: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(BIN)/zarco

setup: $(BIN)/zarco

sim: setup
	mkdir -p out
	$(BIN)/zarco sim config/scenarios/rectangle.toml --report out/rectangle.json --plot out/rectangle.png

test: setup lint
	$(BIN)/python -m pytest -n $(TEST_JOBS) --dist loadfile

lint: setup
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

bench: setup
	$(BIN)/python tests/bench/lines.py

# systemd/requirements.lock: the runtime's dependencies (pyproject.toml) and what builds
# it, at the versions this .venv's tests ran with, for any platform and Python >= 3.11,
# each file's sha256 (systemd/install.sh installs with pip --require-hashes)
lock: setup
	$(BIN)/pip install -q uv
	$(BIN)/pip freeze --exclude-editable > .venv/tested-versions.txt
	$(BIN)/uv pip compile pyproject.toml systemd/build-requirements.in --universal \
	    --python-version 3.11 --generate-hashes --constraint .venv/tested-versions.txt \
	    --custom-compile-command "make lock" --quiet -o systemd/requirements.lock
