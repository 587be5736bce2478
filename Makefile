# procmod: `make test` and `make demo` each work on a fresh machine with Python 3.11 + pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
# The versions the suite last passed with; `make lock` refreshes it (see README "Dependencies").
LOCK   := constraints.txt

.PHONY: install lock test test-slow demo bench clean

# The Blender add-on's tests run Blender as a Python module (bpy, 4.5 LTS). Its wheel declares
# numpy<2, though it runs with procmod's numpy 2 (only Blender's audio module, unused headless,
# needs 1.x), so pip cannot resolve it together with the lock file: it goes in without its
# dependencies.
BPY    := bpy==4.5.*

# compileall writes procmod's bytecode, as pip does for an installed package: where
# PYTHONDONTWRITEBYTECODE is set, an editable install's modules were compiled from source in
# every process (~0.3 s of each command's start-up).
$(STAMP): pyproject.toml $(LOCK)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -c $(LOCK) -e '.[test]'
	$(PY) -m pip install --quiet --no-deps -c $(LOCK) '$(BPY)'
	$(PY) -m compileall -q procmod
	touch $(STAMP)

install: $(STAMP)

# Resolve the newest versions pyproject.toml allows in a scratch venv and pin them in
# $(LOCK) (procmod itself left out; local version labels such as +cpu dropped so the pin
# also matches the machine's own torch file). Run `make test` afterwards and commit both.
lock:
	rm -rf .venv-lock
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet -e '.[test]'
	.venv-lock/bin/python -m pip install --quiet --no-deps '$(BPY)'
	{ echo "# pip constraints: the versions 'make test' last passed with. Refresh: make lock"; \
	  .venv-lock/bin/python -m pip freeze --exclude-editable | sed -e 's/+[A-Za-z0-9.]*$$//'; } > $(LOCK).new
	mv $(LOCK).new $(LOCK)
	rm -rf .venv-lock

test: $(STAMP)
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

demo: $(STAMP)
	$(PY) examples/demo.py demo-output

# The quick benchmark; bench/vs_webppl.py (against WebPPL, installs it from npm), bench/engines_2d.py
# and bench/shapegenetics.py take an hour or more each.
bench: $(STAMP)
	$(PY) bench/forward.py

clean:
	rm -rf $(VENV) demo-output .pytest_cache
