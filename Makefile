# The two commands of the README's quickstart. Both create the virtual environment if missing.
VENV := .venv
PY := $(VENV)/bin/python
SCENARIO ?= crowd_noise_0.1..0.6

.PHONY: run test lint docs venv

# scripts/install.py installs with uv (pip's configuration handed over; pip where uv fails): 20 s
# against pip's 60 to 117 s, the same packages. Python writes each module's bytecode when it is
# first imported, which this machine's environment turns off (PYTHONDONTWRITEBYTECODE): without
# bytecode every test process compiled torch anew (tests 8:10 against 4:50), and compiling all of
# the venv up front (compileall) took 38 s of CI for the tenth of its modules that is imported.
unexport PYTHONDONTWRITEBYTECODE

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) scripts/install.py -e '.[test]'
	touch $@

venv: $(VENV)/.installed

# The first run: the six crowd domains at half the training scenes, two jobs at once, so it shows
# the point in minutes; `python -m sim.run --scenario crowd_noise_0.1..0.6` is the full size.
run: venv
	$(PY) -m sim.run --scenario $(SCENARIO) --jobs 2 --set data.splits.train=150

# worksteal: an idle test worker takes queued tests from a busy one, so the two end together
# (4:09 against 4:47 for xdist's default, which hands out fixed chunks). A worker more than the
# cores was no faster (334.7 s against 331.0 on a fresh clone), nor were the slow tests first
test: venv
	$(PY) -m pytest -q -n auto --dist worksteal --durations=15

lint: venv
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

# The documentation site (docs/, the API reference from the docstrings) into site/; warnings fail.
docs: venv
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet
