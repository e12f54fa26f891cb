# polypore: `make demo` and `make test` work on a fresh machine with Python 3.11.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(VENV)/.installed $@

demo: $(VENV)/.installed
	$(BIN)/polypore mesh frictionless-3d --out results/frictionless-3d-mesh --force
	$(BIN)/polypore mesh dfm-2d --out results/dfm-2d-mesh --force
	$(BIN)/polypore run six-fractures-static --out results/six-fractures-static --force
	$(BIN)/polypore run single-crack --out results/single-crack --force
	$(BIN)/polypore run darcy-dfm-2d --out results/darcy-dfm-2d --force
	$(BIN)/polypore run dfm-2d --out results/dfm-2d --force
	@echo "Results under results/: open solution.pvd in ParaView; PNG plots and summary.json in each folder."

test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n 2

clean:
	rm -rf $(VENV) results build src/*.egg-info
