# Two commands on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup run test test-all test-fast bench docs gallery tables clean

$(STAMP): pyproject.toml setup.py
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "edgetruth needs python >= 3.10"'
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[test]'
	@touch $@

setup: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/edgetruth run

# `make test` (what CI runs) leaves out the tests marked slow -- full-resolution renders, the twins' derivations on
# real photos, kill-and-resume, multi-node Ray, the shipped calibration spec -- so that it fits ~15 min on 2 cores;
# `make test-all` runs them too (~35 min on 2 cores).  Test files run on TEST_WORKERS processes (pytest-xdist; a
# file stays on one worker, so its module fixtures are built once); TEST_WORKERS=0 runs them in this process.
TEST_WORKERS ?= 2
XDIST := $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --dist loadfile)

test: $(STAMP)
	$(PY) -m pytest -q $(XDIST) -m "not slow"

test-all: $(STAMP)
	$(PY) -m pytest -q $(XDIST)

# kept for old scripts: it ran what `make test` runs now
test-fast: test

bench: $(STAMP)
	$(VENV)/bin/edgetruth bench

# The docs site into site/ (offline, strict: a broken link, page or docstring fails; tests/package/test_docs_build.py
# runs the same build); the gallery's pictures (renders under runs/gallery/); the tables quoted from docs/results/.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict

gallery: $(STAMP)
	$(PY) tools/gallery.py

tables: $(STAMP)
	$(PY) tools/results_tables.py

clean:
	rm -rf $(VENV) runs .pytest_cache site build/apisrc
	find . -not -path "./$(VENV)/*" -name "*.nb[ic]" -delete  # numba JIT caches
