"""Shared fixtures: an MPI-safe temporary folder and collective clean-up between tests."""
import gc
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest


@pytest.fixture
def mpi_tmp_path():
    """A temporary folder created on rank 0 and shared with every rank."""
    comm = MPI.COMM_WORLD
    path = tempfile.mkdtemp(prefix="sdm_test_") if comm.rank == 0 else None
    path = Path(comm.bcast(path, root=0))
    yield path
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(autouse=True)
def _collective_cleanup():
    """PETSc destructors are collective: collect garbage on every rank together."""
    yield
    gc.collect()
    MPI.COMM_WORLD.Barrier()
