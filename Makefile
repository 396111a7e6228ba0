# Two commands on a fresh machine: `make demo` and `make test`.
# Every target creates .venv with the machine's python3 and installs the project into it when needed.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SOURCES := mechanism converters tests bench examples

.PHONY: demo test test-fast lint bench clean

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/mechanism demo --out out

# ruff (bugs, not taste), the formatter (100-character lines: `ruff format` fixes what it reports)
# and mypy on the whole package, then every test
lint: $(STAMP)
	$(VENV)/bin/ruff check $(SOURCES)
	$(VENV)/bin/ruff format --check $(SOURCES)
	$(VENV)/bin/mypy

# two pytest workers (pytest-xdist), one per core of the 2-core machines CI and developers have;
# the tests named "ray" run one after another on one worker (tests/conftest.py's scheduler).
# Where the environment forbids bytecode caches (container images set PYTHONDONTWRITEBYTECODE),
# every interpreter the tests start (the workers, the CLI server, the tests that need a fresh one,
# Ray's workers) compiled the package again, and each worker the tests' rewritten asserts (a fresh
# clone's pytest: 320 s with it, 281 s without, back to back). The caches go to __pycache__, which
# git ignores.
PYTEST := env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -q -n 2

test: lint
	$(PYTEST)

# the same without the tests marked slow
test-fast: lint
	$(PYTEST) -m "not slow"

bench: $(STAMP)
	$(PY) -m bench

clean:
	rm -rf out .pytest_cache
