# Two entry points that work on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup demo test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# The CPU wheel of torch lies on this machine; a bare `torch` requirement would pull CUDA.
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e '.[test,learn,cluster]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/auvsim generate --scenario straight --speed 2 --heading-deg 30 --depth 20 \
		--duration 600 --seed 1 --out demo/straight.h5
	$(BIN)/auvsim inspect demo/straight.h5
	$(BIN)/auvsim plot demo/straight.h5

test: $(STAMP)
	$(BIN)/ruff check auvsim beamsnet tests benchmarks
	$(BIN)/pytest -q

bench: $(STAMP)
	$(BIN)/python benchmarks/generation.py
	$(BIN)/python benchmarks/datasets.py

clean:
	rm -rf $(VENV) demo .pytest_cache
