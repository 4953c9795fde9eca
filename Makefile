# Two entry points that work on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup demo test docs lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	# The CPU wheel of torch lies on this machine, where pip looks (uv does not); a bare
	# `torch` requirement would pull CUDA.
	$(BIN)/pip install --quiet torch==2.13.0 uv
	# The rest with uv, in half pip's time on a fresh machine; it keeps the torch installed
	# above, which the package's range admits. Bytecode compiled: see docs/ARCHITECTURE.md.
	$(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -e '.[test,learn,cluster,docs,io]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/auvsim generate --scenario straight --speed 2 --heading-deg 30 --depth 20 \
		--duration 600 --seed 1 --out demo/straight.h5
	$(BIN)/auvsim inspect demo/straight.h5
	$(BIN)/auvsim plot demo/straight.h5

test: $(STAMP)
	$(BIN)/ruff check auvsim beamsnet tests benchmarks
	# Bytecode of the project's own modules, which the editable install leaves uncompiled:
	# where PYTHONDONTWRITEBYTECODE is set (it is on the machines this project is tested
	# on) no process writes it, and each of the hundreds of processes the tests start
	# compiled them again (0.4 s each).
	$(BIN)/python -m compileall -q auvsim beamsnet
	# The site first: a broken link, include or API reference fails here (site/ is ignored).
	# Beside it, numba compiles its kernels into their cache once, so that the test
	# processes load them instead of each compiling them (tests/compile_kernels.py).
	$(BIN)/python tests/compile_kernels.py & kernels=$$!; \
		NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site; built=$$?; \
		wait $$kernels && test $$built -eq 0
	# Two workers, one a core of the 2-core CI machine; the ten slowest tests named at the end.
	# One thread per numerical library in every test process (and what it starts), so
	# that the two workers do not oversubscribe the cores (OpenMP threads that wait by
	# spinning slow everything down).
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(BIN)/pytest -q -n 2 --dist worksteal --durations=10

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve

bench: $(STAMP)
	$(BIN)/python benchmarks/generation.py
	$(BIN)/python benchmarks/datasets.py

clean:
	rm -rf $(VENV) demo site .pytest_cache
