# quadest: two commands on a fresh machine (Python >= 3.11, pip, make):
#   make demo   creates .venv, installs quadest, runs its main job (quadest demo: reproduce afckf)
#   make test   installs the test extra into .venv and runs every test
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= demo-output

.PHONY: demo api test test-unit test-integration test-examples lint wheel-check install clean clean-cache

$(BIN)/python:
	@echo "==> creating virtual environment $(VENV)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml setup.py src/quadest/filters/_stream.c | $(BIN)/python
	@echo "==> installing quadest and its dependencies into $(VENV)"
	$(BIN)/python -m pip install --quiet -e '.[plot,report]'
	@touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	@echo "==> installing the test extra"
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@touch $@

install: $(VENV)/.installed

demo: $(VENV)/.installed
	@$(BIN)/quadest demo --out $(OUT)

test: $(VENV)/.installed-test
	$(BIN)/python -m pytest

# one tier of the tests: unit (a module's behaviour), integration (commands, flights, data,
# docs), examples (every script in examples/ run as a user runs it)
test-unit test-integration test-examples: test-%: $(VENV)/.installed-test
	$(BIN)/python -m pytest tests/$*

$(VENV)/.installed-docs: $(VENV)/.installed
	@echo "==> installing the docs extra (Sphinx)"
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	@touch $@

# the API reference from the docstrings (docs/api), warnings as errors; opens at build/api/index.html
api: $(VENV)/.installed-docs
	$(BIN)/sphinx-build -W --keep-going -q -b html docs/api build/api
	@echo "==> API reference: build/api/index.html"

# ruff's lint and format check over the whole tree (the configuration is in pyproject.toml)
lint: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

# the package as a user installs it: sdist and wheel built, the wheel installed into a new
# virtual environment without extras and checked, then with [logs] (tools/check_wheel.py)
wheel-check: $(VENV)/.installed-test
	$(BIN)/python tools/check_wheel.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache build
	find src -name '*.so' -delete  # the streaming extension, built in place by the editable install

# compiled code is cached per hash of the source (src/quadest/_jit.py), so an edit never
# reuses stale machine code; this removes every cached folder
clean-cache:
	rm -rf $${XDG_CACHE_HOME:-$$HOME/.cache}/quadest/numba
	if [ -n "$$NUMBA_CACHE_DIR" ]; then rm -rf "$$NUMBA_CACHE_DIR"/quadest-*; fi
	find src -name '*.nbi' -delete; find src -name '*.nbc' -delete
