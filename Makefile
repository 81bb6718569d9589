# Two commands on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup run test test-fast bench docs gallery tables clean

$(STAMP): pyproject.toml setup.py
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "edgetruth needs python >= 3.10"'
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[test]'
	@touch $@

setup: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/edgetruth run

# The slow tests (full-resolution renders, ~3 min) fit CI's budget, so `make test` runs them too;
# `make test-fast` leaves them out.  Test files run on TEST_WORKERS processes (pytest-xdist; a file stays on
# one worker, so its module fixtures are built once); TEST_WORKERS=0 runs them in this process.
TEST_WORKERS ?= 2
XDIST := $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --dist loadfile)

test: $(STAMP)
	$(PY) -m pytest -q $(XDIST)

test-fast: $(STAMP)
	$(PY) -m pytest -q $(XDIST) -m "not slow"

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
