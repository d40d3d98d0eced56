# gyrotherm: two commands do everything on a fresh machine (python3 >= 3.11 and make).
#   make demo   set up .venv and run the main job on embedded defaults
#   make test   set up .venv with dev tools and run the full suite (pytest, ruff, mypy)
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
DEVSTAMP := $(VENV)/.installed-dev

.PHONY: demo test setup setup-dev bench findings clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

$(DEVSTAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $@

setup: $(STAMP)
setup-dev: $(DEVSTAMP)

demo: $(STAMP)
	$(PY) -m gyrotherm demo

test: $(DEVSTAMP)
	$(VENV)/bin/ruff check
	$(VENV)/bin/mypy src
	$(PY) -m pytest -q

bench: $(DEVSTAMP)
	$(PY) bench/run_all.py

findings: $(STAMP)
	$(PY) scripts/findings.py

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache .ruff_cache
