# The two set-up commands of the README: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python

.PHONY: demo test system-deps venv bench bench-quick clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

venv: $(VENV)/.installed

system-deps:
	@bash scripts/install-system-deps.sh

demo: venv system-deps
	$(VENV)/bin/twolink reproduce

test: venv system-deps
	$(PY) -m pytest -q

# Benchmarks (benchmarks/run.py): full mode writes the README's figures to
# benchmarks/results.json; quick mode is the CI form (well under two minutes).
bench: venv system-deps
	$(PY) -m benchmarks.run --json benchmarks/results.json

bench-quick: venv system-deps
	$(PY) -m benchmarks.run --quick

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
