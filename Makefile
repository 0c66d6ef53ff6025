# The two set-up commands: `make demo` and `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
OUT    ?= out/demo

.PHONY: demo test test-slow bench clean

$(VENV)/.installed: pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "isophote needs Python 3.11+"'
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install -q --upgrade pip
	@$(PY) -m pip install -q -e '.[test,metrics]'
	@touch $@

demo: $(VENV)/.installed
	@$(PY) examples/demo.py examples/data/chelsea.png $(OUT)

test: $(VENV)/.installed
	@$(PY) -m pytest

test-slow: $(VENV)/.installed  # also the minutes-long checks: the wheel in a fresh venv
	@ISOPHOTE_SLOW_TESTS=1 $(PY) -m pytest tests/test_packaging.py

bench: $(VENV)/.installed
	@$(PY) -m pip install -q -e '.[bench]'
	@$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) out .pytest_cache
