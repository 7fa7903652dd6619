"""Shared fixtures: an MPI-safe temporary folder, collective clean-up between tests, the problem
and scheme registries restored after a test, and a folder made read-only even for root; on several
ranks, a watchdog that ends the run when one rank fails and the others are left waiting."""
import gc
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

#: the MPI launchers' variable prefixes (Open MPI 4 and 5, PMIx, PRRTE, MPICH's Hydra)
_MPI_PREFIXES = ("OMPI_", "PMIX_", "OPAL_", "PRTE_", "HYDRA_", "PMI_")
if os.environ.get("PYTEST_XDIST_WORKER") and "SDM_ENV_BEFORE_MPI" in os.environ:
    # a pytest-xdist worker (make test's serial leg, ``-n 2``) inherits the controller's environment as
    # MPI_Init left it: the controller's singleton job (its PMIx server, its job id). A test's own mpirun
    # started with that environment exits 1 without a word: keep only what the controller started with.
    # (once: a pytest that a test starts under mpirun inherits the worker's variables, and must keep
    # the ones its own launcher set)
    _keep = set(os.environ.pop("SDM_ENV_BEFORE_MPI").split(","))
    for _k in [k for k in os.environ if k.startswith(_MPI_PREFIXES) and k not in _keep]:
        del os.environ[_k]
elif not os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ["SDM_ENV_BEFORE_MPI"] = ",".join(k for k in os.environ if k.startswith(_MPI_PREFIXES))

from mpi4py import MPI  # noqa: E402  (after the environment above: MPI_Init reads it)

import pytest

# pytest-xdist's controller rebuilds a worker's warning by importing the module of its category, in the
# thread that serves that worker: two workers reporting at once deadlocked on importing sdm_dolfinx
# (Python 3.13, dolfinx 0.9's chroot). The modules of the package's warnings are imported here first.
import sdm_dolfinx.contact.friction_bound  # noqa: E402,F401
import sdm_dolfinx.post.render  # noqa: E402,F401
import sdm_dolfinx.run.boundary_sink  # noqa: E402,F401
import sdm_dolfinx.run.linear_range  # noqa: E402,F401


class _Watchdog:
    """Ends a run on several ranks (``os._exit(1)``: mpirun then stops every rank) that would hang.

    A test that fails on one rank only leaves the others inside a collective call the failed rank
    will never make: each of them waits for ever, and a CI job runs out of time instead of reporting.
    On several ranks the failure is printed at once, and if this rank has not started the next test
    (or reached the end of the session together with the others) ``SDM_TEST_DESYNC_SECONDS`` (120) s
    later, the run ends. Any test taking longer than ``SDM_TEST_TIMEOUT`` (1800) s on several ranks
    ends it too (a deadlock without a failure)."""

    def __init__(self):
        self._timer = None
        self.capture = None      # pytest's capture manager: the message must reach the real stderr

    def arm(self, seconds, why):
        self.disarm()
        self._timer = threading.Timer(seconds, self._fire, args=(why,))
        self._timer.daemon = True
        self._timer.start()

    def disarm(self):
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _fire(self, why):
        if self.capture is not None:
            self.capture.suspend_global_capture(in_=False)
        sys.stderr.write(f"\nrank {MPI.COMM_WORLD.rank}: {why}: ending the run\n")
        sys.stderr.flush()
        os._exit(1)


_WATCHDOG = _Watchdog()
_SEVERAL = MPI.COMM_WORLD.size > 1


def pytest_configure(config):
    _WATCHDOG.capture = config.pluginmanager.getplugin("capturemanager")


def pytest_runtest_logstart(nodeid, location):
    if _SEVERAL:
        seconds = float(os.environ.get("SDM_TEST_TIMEOUT", "1800"))
        _WATCHDOG.arm(seconds, f"{nodeid} has run for {seconds:.0f} s on {MPI.COMM_WORLD.size} ranks (SDM_TEST_TIMEOUT)")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    report = (yield).get_result()
    if _SEVERAL and report.failed:
        rank = MPI.COMM_WORLD.rank
        sys.stderr.write(f"\nrank {rank}: FAILED {item.nodeid} ({report.when})\n{report.longreprtext}\n")
        sys.stderr.flush()
        seconds = float(os.environ.get("SDM_TEST_DESYNC_SECONDS", "120"))
        _WATCHDOG.arm(seconds, f"{item.nodeid} failed on this rank and the other ranks did not follow within "
                               f"{seconds:.0f} s (they wait in a collective call this rank left)")


def pytest_sessionfinish(session, exitstatus):
    """Every rank reaches the end together (polled, so that an armed watchdog can still fire)."""
    if _SEVERAL:
        request = MPI.COMM_WORLD.Ibarrier()
        while not request.Test():
            threading.Event().wait(0.01)
        _WATCHDOG.disarm()


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


def _restored(mapping):
    """Yield once, then put ``mapping`` (a registry's dict) back as it was (a fixture's body)."""
    saved = dict(mapping)
    yield
    mapping.clear()
    mapping.update(saved)


@pytest.fixture
def clean_registry():
    """The problem registry as it was before the test (a test's problems must not leak into others)."""
    from sdm_dolfinx.problems import registry
    yield from _restored(registry._REGISTRY)


@pytest.fixture
def clean_schemes():
    """The scheme registry as it was before the test."""
    from sdm_dolfinx import schemes
    yield from _restored(schemes._REGISTRY)


def _read_only(folder, on):
    """Make ``folder`` unwritable even for root (the immutable attribute), or writable again;
    every rank skips together where that cannot be done (no chattr, no attributes)."""
    comm = MPI.COMM_WORLD
    problem = None
    if comm.rank == 0:
        if os.geteuid() == 0:
            try:
                r = subprocess.run(["chattr", "+i" if on else "-i", str(folder)], capture_output=True)
                problem = r.stderr.decode().strip() if r.returncode != 0 and on else None
            except FileNotFoundError:
                problem = "no chattr"
        else:
            folder.chmod(0o555 if on else 0o755)
    problem = comm.bcast(problem, root=0)
    if problem:
        pytest.skip(f"cannot make a folder read-only for root here: {problem}")


@pytest.fixture
def read_only():
    """``read_only(folder, on)``: a folder unwritable even for root (``on``), or writable again."""
    return _read_only
