# The two set-up commands of the README: `make demo` and `make test`.
# PYTHON picks the interpreter (3.11 to 3.13); a .venv of another version is rebuilt.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
# The installed-stamps name the interpreter's version, so a new PYTHON misses them.
PYVER := $(shell $(PYTHON) -c 'import platform; print(platform.python_version())' 2>/dev/null)

.PHONY: demo test system-deps venv venv-test bench bench-quick docs docs-serve clean results

# demo needs twolink alone; test and the benchmarks also need '.[test]' (pytest and
# the peer libraries the benchmarks and tests compare against).
$(VENV)/.installed-$(PYVER): pyproject.toml scripts/venv.sh
	bash scripts/venv.sh $(PYTHON) $(VENV)
	touch $@

$(VENV)/.installed-test-$(PYVER): pyproject.toml scripts/venv.sh
	bash scripts/venv.sh $(PYTHON) $(VENV) test
	touch $@ $(VENV)/.installed-$(PYVER)

venv: $(VENV)/.installed-$(PYVER)

venv-test: $(VENV)/.installed-test-$(PYVER)

system-deps:
	@bash scripts/install-system-deps.sh

demo: venv system-deps
	$(VENV)/bin/twolink reproduce

# PYTEST_ARGS narrows a run (CI's second interpreter: -m "not slow"); empty: the whole suite.
PYTEST_ARGS ?=
test: venv-test system-deps
	$(PY) -m pytest -q -n 2 $(PYTEST_ARGS)

# Benchmarks (benchmarks/run.py): full mode writes the README's figures to
# benchmarks/results.json; quick mode is the CI form (well under two minutes).
bench: venv-test system-deps
	$(PY) -m benchmarks.run --json benchmarks/results.json

bench-quick: venv-test system-deps
	$(PY) -m benchmarks.run --quick

# The documentation site (scripts/build-docs.sh installs the docs extra into the venv):
# docs builds it strictly into build/site; docs-serve shows it at http://127.0.0.1:8000.
docs: venv
	bash scripts/build-docs.sh $(VENV)

docs-serve: docs
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs serve

# The committed results (renders/, docs/data/reproduce.json), regenerated on purpose: the
# studies with TWOLINK_OUTPUT=renders, then docs/generate.py (scripts/results.sh; hours for
# all of them). STEPS picks some: make results STEPS="leaderboard-md docs".
STEPS ?=
results: venv
	bash scripts/results.sh $(VENV) $(STEPS)

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
