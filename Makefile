# The two commands of the README's quickstart. Both create the virtual environment if missing.
VENV := .venv
PY := $(VENV)/bin/python
SCENARIO ?= crowd_noise_0.1..0.6

.PHONY: run test lint venv

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --no-compile -e '.[test]'
	touch $@

venv: $(VENV)/.installed

run: venv
	$(PY) -m sim.run --scenario $(SCENARIO)

test: venv
	$(PY) -m pytest -q -n auto

lint: venv
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .
