# polypore: `make demo` and `make test` work on a fresh machine with Python 3.11.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test test-fast test-mpi clean

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

# the lint covers the layers issue 27 names; the rest of src/ joins as it is cleaned
LINTED := src/polypore/solvers src/polypore/models src/polypore/assembly src/polypore/parallel

test: $(VENV)/.installed-test
	$(BIN)/ruff check $(LINTED)
	$(BIN)/mypy $(LINTED)
	$(BIN)/python -m pytest -q -n 2

# The optional extras 'fast' (PARDISO through pypardiso, ~950 MB of MKL wheels) and 'amg', in a
# venv of their own so that `make test` keeps testing the default install; the whole suite runs
# with PARDISO as the 3D direct solver, and tests/unit/solvers/test_fast_extra.py fails if it did not install.
VENV_FAST := .venv-fast
BIN_FAST  := $(VENV_FAST)/bin

$(VENV_FAST)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV_FAST)
	$(BIN_FAST)/python -m pip install --quiet --upgrade pip
	$(BIN_FAST)/python -m pip install --quiet -e '.[test,fast,amg]'
	touch $@

test-fast: $(VENV_FAST)/.installed
	POLYPORE_REQUIRE_PARDISO=1 $(BIN_FAST)/python -m pytest -q -n 2

# MPI/PETSc tests (docs/parallel.md): Debian's PETSc 3.18 (hypre, MUMPS) and Open MPI through
# python3-petsc4py/python3-mpi4py, seen from a venv of this Python with numpy<2 (the Debian builds
# need it) through a .pth file; apt-get runs only when they are missing (as root, as CI is).
VENV_MPI := .venv-mpi
BIN_MPI  := $(VENV_MPI)/bin
PETSC_SITE = $(firstword $(wildcard /usr/lib/petscdir/petsc3.*/x86_64-linux-gnu-real/lib/python3/dist-packages))

$(VENV_MPI)/.debian-petsc:
	@if [ -z "$(PETSC_SITE)" ] || [ ! -d /usr/lib/python3/dist-packages/mpi4py ]; then \
	  if [ "$$(id -u)" != 0 ]; then \
	    echo "test-mpi: Debian's python3-petsc4py and python3-mpi4py are not installed; as root run" \
	         "'apt-get install -y python3-petsc4py python3-mpi4py' (docs/parallel.md)" >&2; exit 1; fi; \
	  echo "test-mpi: installing python3-petsc4py python3-mpi4py (Debian)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-petsc4py python3-mpi4py \
	    openmpi-bin >/dev/null; fi
	$(PYTHON) -m venv $(VENV_MPI)
	$(BIN_MPI)/python -m pip install --quiet --upgrade pip
	@# petsc4py from PETSc's real-scalar site dir; mpi4py alone from Debian's (not its numpy or scipy)
	mkdir -p $(VENV_MPI)/debian && ln -sfn /usr/lib/python3/dist-packages/mpi4py $(VENV_MPI)/debian/mpi4py
	D=$$(ls -d /usr/lib/petscdir/petsc3.*/x86_64-linux-gnu-real/lib/python3/dist-packages | head -1) && \
	SP=$$($(BIN_MPI)/python -c "import sysconfig; print(sysconfig.get_paths()['purelib'])") && \
	printf '%s\n%s\n' "$$D" "$(abspath $(VENV_MPI))/debian" > "$$SP/debian-petsc.pth"
	touch $@

$(VENV_MPI)/.installed: pyproject.toml $(VENV_MPI)/.debian-petsc
	$(BIN_MPI)/python -m pip install --quiet -e '.[test,mpi]' 'numpy<2'
	$(BIN_MPI)/python -c "from petsc4py import PETSc; from mpi4py import MPI; import numpy; \
	  print('test-mpi: PETSc', '.'.join(map(str, PETSc.Sys.getVersion())), '|', MPI.Get_library_version().split(',')[0], \
	  '| numpy', numpy.__version__)"
	touch $@

test-mpi: $(VENV_MPI)/.installed
	$(BIN_MPI)/python -m pytest -q tests/mpi/test_petsc_solvers.py tests/mpi/test_petsc_mpi.py

clean:
	rm -rf $(VENV) $(VENV_FAST) $(VENV_MPI) results build src/*.egg-info
