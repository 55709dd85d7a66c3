# dcfvision: `make demo` runs the demo, `make test` runs ruff and the tests.
# Both create .venv on first use and reuse it while pyproject.toml is unchanged.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench venv clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet ".[dev,bench]"
	touch $(STAMP)

demo: $(STAMP)
	$(PY) infer.py demo

lint: $(STAMP)
	$(VENV)/bin/ruff check .

test: lint
	$(PY) -m pytest

bench: $(STAMP)
	$(PY) bench/triangulation.py --json --plot docs/figures/triangulation.png

clean:
	rm -rf $(VENV) build *.egg-info
