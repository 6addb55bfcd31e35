# Two entry points (see README): `make sim` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup sim test lint bench
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
	$(BIN)/python -m pytest

lint: setup
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

bench: setup
	$(BIN)/python tests/bench/lines.py
