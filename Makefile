# frictionuq: the two commands of the README.
#   make demo   create .venv, install frictionuq, run the main job on the shipped data
#               (workflows/quick.toml -> reports/quick/index.html)
#   make test   create .venv, install frictionuq with its test extra and Debian's chromium (for
#               the report's browser test; tools/install-chromium), run the test suite
# A Python >= 3.12 is found by tools/find-python (PATH, then pyenv's versions); override with
#   make demo PYTHON=/path/to/python3.12
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PYTHON_FOUND = $(shell tools/find-python)

.PHONY: demo test install install-test bench bench-fit bench-discover clean-venv

demo: $(VENV)/.installed
	$(VENV)/bin/frictionuq run workflows/quick.toml -j 2

test: $(VENV)/.installed-test
	@tools/install-chromium >/dev/null
	$(PY) -m pytest

bench: $(VENV)/.installed-test
	$(PY) benchmarks/bench_simulator.py

bench-fit: $(VENV)/.installed-test
	$(PY) benchmarks/bench_fit.py

bench-discover: $(VENV)/.installed-test
	$(PY) benchmarks/bench_discover.py --verbose

install: $(VENV)/.installed
install-test: $(VENV)/.installed-test

$(VENV)/.created:
	@py="$(PYTHON_FOUND)"; [ -n "$$py" ] || exit 1; \
	echo "using $$py ($$($$py --version))"; \
	"$$py" -m venv $(VENV) && $(PY) -m pip install -q -U pip
	@touch $@

$(VENV)/.installed: $(VENV)/.created pyproject.toml
	$(PY) -m pip install -q -e .
	@touch $@

$(VENV)/.installed-test: $(VENV)/.created pyproject.toml
	$(PY) -m pip install -q -e ".[test]"
	@touch $@ $(VENV)/.installed

clean-venv:
	rm -rf $(VENV)
