# calf-nurbs: the two set-up commands are `make run` and `make test` (Python 3.11).
PYTHON ?= python3.11
VENV   ?= .venv
BIN    := $(VENV)/bin
HOST   ?= 127.0.0.1
PORT   ?= 8000

.PHONY: run test install bench openapi clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/activate
	$(BIN)/pip install -e '.[test,postgres]'
	touch $(VENV)/.installed

install: $(VENV)/.installed

run: install
	$(BIN)/calf-nurbs serve --host $(HOST) --port $(PORT)

test: install
	$(BIN)/python -m pytest

bench: install
	$(BIN)/python benchmarks/bench_fit.py

openapi: install
	$(BIN)/python -m app.openapi_export

clean:
	rm -rf $(VENV) var .pytest_cache
