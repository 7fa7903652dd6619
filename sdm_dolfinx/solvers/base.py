"""What the step solvers share: the error they raise when a step's variational inequality is not
solved, and Murty's rule, which ends the cycles of their active-set (semi-smooth Newton) loops."""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.errors import SdmError


class VIError(SdmError, RuntimeError):
    """A step's variational inequality was not solved (the message says why: PETSc's or the
    active set's reason)."""


class MurtyRule:
    """Murty's rule for one step's active-set iterations: once the number of violated conditions
    has not decreased for :data:`PATIENCE` iterations, only the violated condition of largest
    global index changes, which ends the cycles full updates can fall into.

    ``gidx``: the global index of each local condition; one instance per step (collective)."""

    #: iterations without a decrease before single exchanges
    PATIENCE = 3

    def __init__(self, gidx, comm):
        self.gidx, self.comm = gidx, comm
        self.best, self.patience = np.inf, self.PATIENCE

    def single(self, n_bad, bad):
        """None while ``n_bad`` (the global count) falls or patience is left; else the mask of the
        one condition of ``bad`` with the largest global index over the ranks."""
        if n_bad < self.best:
            self.best, self.patience = n_bad, self.PATIENCE
            return None
        if self.patience > 0:
            self.patience -= 1
            return None
        return self.gidx == self.comm.allreduce(int(np.max(self.gidx[bad], initial=-1)), op=MPI.MAX)
