# Two commands on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup run test test-fast bench clean

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

clean:
	rm -rf $(VENV) runs .pytest_cache
	find . -not -path "./$(VENV)/*" -name "*.nb[ic]" -delete  # numba JIT caches
