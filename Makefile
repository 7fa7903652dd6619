# sdm_dolfinx: `make demo` runs the membrane comparison, `make test` mypy on the package (`make
# typecheck`), then the tests on 1 and 2 ranks.
# Both first install what is missing (Debian packages, .venv); see scripts/setup.sh.
SHELL := /bin/bash
PY := .venv/bin/python
NP ?= 2
# Debian's OpenMPI refuses to run as root without these; shared memory only on one machine.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_btl := self,vader
export OMPI_MCA_rmaps_base_oversubscribe := 1
export OMPI_MCA_mpi_yield_when_idle := 1
MPIRUN := mpirun -n $(NP)
# the serial leg in JOBS pytest-xdist workers (Debian's python3-pytest-xdist), a test file per worker
# (its module fixtures computed once); JOBS=1 runs it in one process
JOBS ?= 2
XDIST := $(if $(filter-out 1,$(JOBS)),-n $(JOBS) --dist loadfile)
STAMP := .venv/.installed

.PHONY: setup typecheck test test-serial test-mpi demo clean

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh
	touch $@

setup: $(STAMP)

test: setup
	$(MAKE) --no-print-directory typecheck
	$(MAKE) --no-print-directory test-serial
	$(MAKE) --no-print-directory test-mpi

# mypy with pyproject.toml's [tool.mypy]: the package with the default rules, the public API
# strictly (docs/testing.md); scripts/setup.sh installs the pinned mypy
typecheck: setup
	$(PY) -m mypy

test-serial: setup
	$(PY) -m pytest -q $(XDIST) tests

test-mpi: setup
	$(MPIRUN) $(PY) -m mpi4py -m pytest -q tests

demo: setup
	$(PY) demos/membrane.py

clean:
	rm -rf .venv output demos/output *.egg-info .mypy_cache

# The same suite on current FEniCSx in a Debian 13 (trixie) chroot, built once (~5 min, ~3 GB) under
# /var/cache/sdm_dolfinx and reused; needs root. See scripts/debian13.sh. test-dolfinx09: Debian 13's
# dolfinx 0.9; test-dolfinx011: PyPI's wheel dolfinx-solver-real (dolfinx 0.11, PETSc 3.25 without
# SuiteSparse or hypre, MPICH) in a venv inside it. SERIAL_MARK / MPI_MARK: pytest -m expressions
# choosing each leg's tests (CI: .ci/run).
.PHONY: test-dolfinx09 test-dolfinx011
test-dolfinx09: setup
	NP=$(NP) JOBS=$(JOBS) SDM_DOLFINX=0.9 bash scripts/debian13.sh test

test-dolfinx011: setup
	NP=$(NP) JOBS=$(JOBS) SDM_DOLFINX=0.11 bash scripts/debian13.sh test

# The paper's figures, Table 2 and an HTML report regenerated from the runs' files (see
# sdm_dolfinx/paper/): `make figures` runs the full study into output/study (81 runs, about
# 19 min on 2 cores, 13 of them the paper's finest disc, 513k dofs, 1.0 GB; resumable: a rerun
# computes only what is missing) and writes report/; `make figures QUICK=1` (or
# `make figures-quick`) is the two-minute version -> output/report-quick.
# FIGURES_ARGS="--disc-max-level 5" stops the disc convergence study at 126k dofs.
.PHONY: figures figures-quick
figures: setup
	nice -n 10 $(PY) -m sdm_dolfinx figures $(if $(QUICK),--quick) $(FIGURES_ARGS)

figures-quick: setup
	$(PY) -m sdm_dolfinx figures --quick

# ParaView's own reader on real output: installs Debian's paraview and xvfb if missing (about 2 min,
# ~790 MB), runs a short membrane run, checks every array at every time step with pvpython
# (Xdmf3ReaderS), renders a PNG under xvfb-run, then runs tests/integration/test_paraview.py. See docs/install.md.
.PHONY: paraview-check
paraview-check: setup
	@command -v pvpython >/dev/null && command -v xvfb-run >/dev/null || { \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO="sudo"; \
	  echo "paraview-check: installing the Debian packages paraview xvfb"; \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq paraview xvfb >/dev/null; }
	$(PY) -m sdm_dolfinx membrane --N 10 --dt 1e-3 --T 0.5 --write-every 20 --out output/paraview-check --overwrite --quiet
	xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython scripts/paraview_check.py output/paraview-check --json output/paraview-check/paraview.json --png output/paraview-check/paraview.png
	$(PY) -m pytest -q tests/integration/test_paraview.py
