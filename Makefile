# The two commands of the README's quickstart. Both create the virtual environment if missing.
VENV := .venv
PY := $(VENV)/bin/python
SCENARIO ?= crowd_noise_0.1..0.6

.PHONY: run test lint docs venv

# scripts/install.py installs with uv (pip's configuration handed over; pip where uv fails): 20 s
# against pip's 60 to 117 s, the same packages. Neither compiles bytecode; compileall does it on
# all cores, and without it every test process compiled torch's modules anew (tests 8:10 vs 4:50).
# A few third-party files are for newer Pythons and do not compile: pip skips them too (|| true).
# Packages' own test folders are never imported here: skipping them saves a third (34 -> 22 s).
$(VENV)/.installed: pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) scripts/install.py -e '.[test]'
	$(PY) -m compileall -q -j 0 -x '/tests/' $(VENV)/lib > /dev/null || true
	touch $@

venv: $(VENV)/.installed

run: venv
	$(PY) -m sim.run --scenario $(SCENARIO)

test: venv
	$(PY) -m pytest -q -n auto --dist loadgroup --durations=15

lint: venv
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

# The documentation site (docs/, the API reference from the docstrings) into site/; warnings fail.
docs: venv
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet
