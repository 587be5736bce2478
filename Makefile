# procmod: `make test` and `make demo` each work on a fresh machine with Python 3.11 + pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: install test test-slow demo bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

demo: $(STAMP)
	$(PY) examples/demo.py demo-output

# The quick benchmarks; bench/engines_2d.py and bench/shapegenetics.py take about half an hour each.
bench: $(STAMP)
	$(PY) bench/forward.py
	$(PY) bench/smc_vines.py

clean:
	rm -rf $(VENV) demo-output .pytest_cache
