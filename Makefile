# dexaug: `make demo` runs the main job on its embedded default, `make test` runs the tests.
# Both create .venv and install the project on first use (a fresh clone needs nothing else).
# `make demo` installs only the package and what it needs; `make test` adds the `dev` and `ray`
# extras (pytest, ruff, playwright, a local Ray cluster). Both install the versions pinned in
# constraints.txt (see its header to regenerate it).

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
CONSTRAINTS := constraints.txt
PIP_INSTALL := $(BIN)/python -m pip install --quiet -c $(CONSTRAINTS)
DEMO_STAMP := $(VENV)/.installed-demo
TEST_STAMP := $(VENV)/.installed-test
export MUJOCO_GL ?= egl

.PHONY: demo test test-fast test-load lint bench bench-headline bench-headline-quick clean gl browser docs

# The virtual environment itself (kept if it is already there), for both installs below.
define make-venv
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
endef

# Base package only: what `dexaug demo` (and the benchmarks' scripts) need. No bytecode is
# compiled at install (94 MB for every module of every package, measured): Python writes it
# for the modules a run imports, when it first imports them.
$(DEMO_STAMP): pyproject.toml $(CONSTRAINTS)
	$(make-venv)
	$(PIP_INSTALL) --no-compile -e .
	touch $@

# The package with the test tooling and Ray.
$(TEST_STAMP): pyproject.toml $(CONSTRAINTS)
	$(make-venv)
	$(PIP_INSTALL) -e '.[dev,ray,envs,lerobot]'
	touch $@

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
browser: $(TEST_STAMP)
	@command -v chromium >/dev/null \
	  || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	       && (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
	       || echo "note: no chromium; browser tests will be skipped"; }
	@grep -qs '"version": "$(IWER_VERSION)"' $(NODE_PREFIX)/node_modules/iwer/package.json \
	  || { command -v npm >/dev/null && npm install --silent --no-audit --no-fund --prefix $(NODE_PREFIX) iwer@$(IWER_VERSION) >/dev/null \
	       || echo "note: no npm or iwer@$(IWER_VERSION) not installable; browser tests will be skipped"; }

demo: $(DEMO_STAMP) gl
	$(BIN)/dexaug demo

test: $(TEST_STAMP) gl browser
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=15

# The quick tier (~30 s on 2 cores): every test but those marked slow (files over ~3 s) or
# browser (headless Chromium); for the edit-test loop. `make test` is what CI runs.
test-fast: $(TEST_STAMP) gl
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not slow and not browser" --durations=5

# The timing-sensitive tests again with the other cores busy (scripts/under_load.sh).
test-load: $(TEST_STAMP) gl
	bash scripts/under_load.sh

lint: $(TEST_STAMP)
	$(BIN)/ruff check .

bench: $(DEMO_STAMP) gl
	$(BIN)/python benchmarks/bench_validate.py
	$(BIN)/python benchmarks/bench_augment.py
	$(BIN)/dexaug bench paper

# The benchmarks behind the README's Status figures and the docs' recorded figures
# (benchmarks/headline.toml), each writing its record under benchmarks/measured/, then the
# figures rewritten from the newest records (~15 min on 2 cores). Commit the records with the
# rewritten README/docs: tests/test_headline_figures.py compares the two.
bench-headline: $(DEMO_STAMP) gl
	$(BIN)/python benchmarks/headline.py run
	$(BIN)/python benchmarks/headline.py render

# The same benchmarks at CI size (~3 min), records in a scratch folder; checks that every
# figure still computes from what they write. Changes no file.
bench-headline-quick: $(DEMO_STAMP) gl
	$(BIN)/python benchmarks/headline.py run --quick

# The guides as a site (mkdocs.yml) in site/: open site/index.html. Strict: a broken link or
# anchor, or a page outside the nav, fails the build (tests/test_docs_site.py builds it too).
docs: $(TEST_STAMP)
	$(BIN)/python -m mkdocs build --strict

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
