# sdm_dolfinx: `make demo` runs the membrane comparison, `make test` the tests on 1 and 2 ranks.
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
STAMP := .venv/.installed

.PHONY: setup test test-serial test-mpi demo clean

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh
	touch $@

setup: $(STAMP)

test: setup
	$(MAKE) --no-print-directory test-serial
	$(MAKE) --no-print-directory test-mpi

test-serial: setup
	$(PY) -m pytest -q tests

test-mpi: setup
	$(MPIRUN) $(PY) -m mpi4py -m pytest -q tests

demo: setup
	$(PY) demos/membrane.py

clean:
	rm -rf .venv output demos/output *.egg-info

# The same suite on dolfinx 0.9: Debian 13 (trixie) in a chroot, built once (~5 min, ~3 GB)
# under /var/cache/sdm_dolfinx and reused; needs root. See scripts/dolfinx09.sh.
.PHONY: test-dolfinx09
test-dolfinx09:
	NP=$(NP) bash scripts/dolfinx09.sh test
