"""Stopping a run cleanly: SIGINT/SIGTERM (or an observer) ask for a stop at the end of a step."""
import signal

from mpi4py import MPI

from sdm_dolfinx.errors import SdmError


class Interrupted(SdmError, RuntimeError):
    """The run stopped at the end of a step on request (SIGINT/SIGTERM), after a checkpoint."""

    def __init__(self, message: str, signum: int) -> None:
        super().__init__(message)
        self.signum = signum


class StopFlag:
    """SIGINT/SIGTERM set a flag; :meth:`agreed` tells every rank whether any rank saw one."""

    def __init__(self, enabled):
        self.signum = 0
        self.old = {}
        if enabled:
            for s in (signal.SIGINT, signal.SIGTERM):
                self.old[s] = signal.signal(s, self._handler)

    def _handler(self, signum, frame):
        self.signum = signum

    def agreed(self, comm, requested=False):
        """The signal number every rank acts on (0: go on); ``requested``: an observer asked
        for a stop (counts as SIGTERM)."""
        return comm.allreduce(max(self.signum, signal.SIGTERM if requested else 0), op=MPI.MAX)

    def restore(self):
        for s, h in self.old.items():
            signal.signal(s, h)
