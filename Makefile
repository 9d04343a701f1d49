# dexaug: `make demo` runs the main job on its embedded default, `make test` runs the tests.
# Both create .venv and install the project on first use (a fresh clone needs nothing else).

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= egl

.PHONY: demo test lint bench clean gl browser

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,ray]'
	touch $(STAMP)

# Offscreen rendering needs an EGL or OSMesa library; install Debian's when we may (root, apt).
gl:
	@$(BIN)/python -c "import ctypes.util,sys; sys.exit(0 if ctypes.util.find_library('EGL') or ctypes.util.find_library('OSMesa') else 1)" 2>/dev/null \
	  || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	       && (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libegl1 libosmesa6 >/dev/null) \
	       || echo "note: no EGL/OSMesa library; rendering tests will be skipped"; }

# Browser tests (the headset page) need Debian's Chromium and the pinned IWER npm package; install
# them when we may (root + apt-get; npm), else the tests skip saying why.
IWER_VERSION := 2.5.0
NODE_PREFIX := $(VENV)/node
browser: $(STAMP)
	@command -v chromium >/dev/null \
	  || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	       && (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
	       || echo "note: no chromium; browser tests will be skipped"; }
	@grep -qs '"version": "$(IWER_VERSION)"' $(NODE_PREFIX)/node_modules/iwer/package.json \
	  || { command -v npm >/dev/null && npm install --silent --no-audit --no-fund --prefix $(NODE_PREFIX) iwer@$(IWER_VERSION) >/dev/null \
	       || echo "note: no npm or iwer@$(IWER_VERSION) not installable; browser tests will be skipped"; }

demo: $(STAMP) gl
	$(BIN)/dexaug demo

test: $(STAMP) gl browser
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

bench: $(STAMP) gl
	$(BIN)/python benchmarks/bench_validate.py
	$(BIN)/python benchmarks/bench_augment.py
	$(BIN)/dexaug bench paper

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
