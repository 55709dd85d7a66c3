# dcfvision: `make demo` runs the demo, `make test` runs ruff and the tests.
# Both create .venv on first use (the full install: .[train,dev,bench]) and reuse it while pyproject.toml is
# unchanged. The torch-free deployment runtime alone is `pip install '.[runtime]'` (docs/deployment.md).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast lint bench venv clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet ".[train,dev,bench]"
	touch $(STAMP)

# make demo [ONLY="vos localization"] [QUICK=1]: every part (or some), full size (or the one-minute smoke run).
demo: $(STAMP)
	$(PY) infer.py demo $(if $(ONLY),--only $(ONLY)) $(if $(QUICK),--quick)

lint: $(STAMP)
	$(VENV)/bin/ruff check .

test: lint
	$(PY) -m pytest

# The suite without the tests marked slow (compile, LightningCLI fits, ONNX exports): under 2 minutes.
test-fast: lint
	$(PY) -m pytest -m "not slow"

# Full benchmarks (minutes each); real data is read from $(SHARED) when present.
SHARED ?= ../shared/data
bench: $(STAMP)
	mkdir -p docs/figures
	$(PY) -m bench.triangulation --points 1000000 --compile --json --plot docs/figures/triangulation.png
	$(PY) -m bench.point_tracking --sintel $(SHARED)/sintel/alley_1/clean $(SHARED)/sintel/alley_1/final \
		$(wildcard $(SHARED)/middlebury/*) --synthetic --stress --methods ccot mosse klt --json \
		--plot docs/figures/point_tracking.png
	$(PY) -m bench.point_tracking --roundtrip $(wildcard $(SHARED)/davis2016/JPEGImages/240p/*) \
		--methods ccot mosse klt --json --plot outputs/point_tracking_roundtrip.png
	cp outputs/point_tracking_roundtrip_conditions.png docs/figures/
	$(PY) -m bench.localization --json --plot docs/figures/localization.png
	$(PY) -m bench.vos --synthetic --json

clean:
	rm -rf $(VENV) build *.egg-info
