# Two commands for a fresh machine: `make demo` and `make test`. Everything else is reached from them.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
TORCH_VERSION := 2.13.0
STAMP  := $(VENV)/.installed
PYTEST_ARGS ?=
# Test processes: each test file runs whole in one of them (its fixtures are made once).
PYTEST_WORKERS ?= 2

.PHONY: setup demo test test-fast lint bench clean

setup: $(STAMP)

# The stamp is remade when the dependency list changes. torch goes first and pinned so that the
# project's `torch` range is already satisfied and pip does not pull the CUDA build.
$(STAMP): pyproject.toml scripts/ensure_system_deps.sh
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; install Python 3.11 (or run make PYTHON=/path/to/python3.11)" >&2; exit 1; }
	bash scripts/ensure_system_deps.sh
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==$(TORCH_VERSION)
	$(BIN)/python -m pip install --quiet -e '.[dev,ouster,physics,blocks]'
	$(BIN)/python -c "import open3d, torch, cv2, rig, calib, slam_bridge, splat, eval" 
	touch $(STAMP)

# The main job: simulate a room, record it through the mock devices, reconstruct and score it.
demo: setup
	$(BIN)/lts demo

test: setup
	bash scripts/ensure_test_tools.sh
	$(BIN)/python -m pytest -n $(PYTEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

# Everything but the slow end-to-end tests, for a quick local loop.
test-fast: setup
	$(BIN)/python -m pytest -m "not slow" -n $(PYTEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

bench: setup
	$(BIN)/lts bench raster --json

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
