# calf-nurbs: the two set-up commands are `make run` and `make test` (Python 3.11).
PYTHON ?= python3.11
VENV   ?= .venv
BIN    := $(VENV)/bin
HOST   ?= 127.0.0.1
PORT   ?= 8000

.PHONY: run test test-slow lint install bench openapi clean web-vendor

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/activate
	$(BIN)/pip install -e '.[test,postgres]'
	touch $(VENV)/.installed

install: $(VENV)/.installed

run: install
	$(BIN)/calf-nurbs serve --host $(HOST) --port $(PORT)

# the suite without the slow end-to-end tests (marked slow: browsers, fuzzers, served
# processes, corpora); test-slow runs those; .ci/run runs both
test: install
	$(BIN)/python -m pytest

test-slow: install
	$(BIN)/python -m pytest -m slow

# style and the numerical core's types (settings in pyproject.toml); .ci/run runs it
lint: install
	$(BIN)/ruff check app tests benchmarks
	$(BIN)/mypy

bench: install
	$(BIN)/python benchmarks/bench_fit.py
	$(BIN)/python benchmarks/bench_service.py
	$(BIN)/python benchmarks/ratios.py

openapi: install
	$(BIN)/python -m app.openapi_export

# three.js for the workbench, from the npm registry at the version app/web/package.json
# pins, into app/web/vendor/three (committed: `make run` needs no Node)
web-vendor:
	cd app/web && npm pack three@$$(python3 -c 'import json; print(json.load(open("package.json"))["dependencies"]["three"])') --silent \
	  && tar xzf three-*.tgz && cp package/build/three.module.js package/build/three.core.js package/LICENSE vendor/three/ \
	  && sed "s#from 'three';#from './three.module.js';#" package/examples/jsm/controls/OrbitControls.js > vendor/three/OrbitControls.js \
	  && rm -rf package three-*.tgz

clean:
	rm -rf $(VENV) var .pytest_cache
