# The two commands a newcomer needs: `make demo` and `make test`. Each creates .venv
# when needed and installs the core and every package under plugins/ into it.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PLUGIN_DIRS := $(patsubst %/pyproject.toml,%,$(wildcard plugins/*/pyproject.toml))

.PHONY: demo test lint bench install clean

install: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml $(addsuffix /pyproject.toml,$(PLUGIN_DIRS))
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e ".[dev]" $(addprefix -e ./,$(PLUGIN_DIRS))
	touch $@

demo: install
	$(BIN)/parsel demo

test: install
	$(BIN)/ruff check .
	PARSEL_STRICT_PLUGINS=1 $(BIN)/python -m pytest

bench: install
	$(BIN)/python benchmarks/bench_cas.py
	$(BIN)/python benchmarks/bench_deform.py

clean:
	rm -rf $(VENV) *.egg-info plugins/*/*.egg-info
