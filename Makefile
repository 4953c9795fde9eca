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
	$(BIN)/pip install --quiet -e '.[test,learn]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/auvsim generate --scenario straight --speed 2 --heading-deg 30 --depth 20 \
		--duration 600 --seed 1 --out demo/straight.h5
	@$(BIN)/python -c "from auvsim.dataset import open_dataset; \
		f = open_dataset('demo/straight.h5'); m = f['missions/mission_000/truth']; \
		print('demo/straight.h5 holds', len(m['time']), 'truth samples; last speed', \
		m['velocity_body'][-1].round(3), 'm/s (body), depth', m['position_ned'][-1, 2].round(2), 'm')"

test: $(STAMP)
	$(BIN)/ruff check auvsim beamsnet tests benchmarks
	$(BIN)/pytest -q

bench: $(STAMP)
	$(BIN)/python benchmarks/generation.py
	$(BIN)/python benchmarks/datasets.py

clean:
	rm -rf $(VENV) demo .pytest_cache
