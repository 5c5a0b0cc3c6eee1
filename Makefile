# The two commands a newcomer types (see README.md):
#   make main   -> runs the flagship studies and writes reports/
#   make test   -> runs the test suite (what CI runs)
SHELL := /bin/bash

.PHONY: main test test-fast lint bench venv browser

venv:
	@scripts/bootstrap.sh >/dev/null

# The venv and a headless Chromium for the report's browser test: a test-only need (apt-get, a
# few hundred MB), so `make main` never installs it.
browser:
	@scripts/bootstrap.sh --browser >/dev/null

main: venv
	.venv/bin/python -m bayesfric main

# Both cores (or up to four): pytest-xdist runs whole test files per worker (--dist loadfile), so a
# file's module-scoped fixtures and compiled programs are built once; workers share the compile cache.
PYTEST_PARALLEL := -n auto --maxprocesses 4 --dist loadfile

test: browser
	.venv/bin/python -m ruff check bayesfric tests benchmarks data examples scripts
	.venv/bin/python -m pytest -q $(PYTEST_PARALLEL)

test-fast: venv
	.venv/bin/python -m pytest -q -m fast $(PYTEST_PARALLEL)

lint: venv
	.venv/bin/python -m ruff check bayesfric tests benchmarks data examples scripts

bench: venv
	.venv/bin/python benchmarks/bench_fit.py
	.venv/bin/python benchmarks/bench_refit.py
