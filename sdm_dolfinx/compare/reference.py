"""Field errors against a reference run, for the problems without an exact solution (membrane,
disc, block), as the paper's convergence study measures them (Table 2): the run's stored
displacement interpolated onto the reference mesh (:func:`sdm_dolfinx.post.interpolate_nonmatching`)
minus the reference's, at the times both stored (every run of the comparison stores
:data:`~sdm_dolfinx.compare.grid.SAMPLES` states)."""
import math

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx import compat, post
from sdm_dolfinx.post import metrics as cm

#: two stored times are the same time to this relative tolerance
SAME_TIME = 1e-9


def read_series(folder):
    """A run's time series, read on the calling rank."""
    return sdm_io.read_timeseries(folder, MPI.COMM_SELF)


class _Stored:
    """A run's stored displacements (state.h5) with its rebuilt spaces (collective)."""

    def __init__(self, folder, comm):
        self.info, self.problem, self.W, Vs = post.rebuild(folder, comm)
        self.reader = sdm_io.StateReader(folder, self.W, Vs, comm)

    def at(self, i):
        return self.reader.read(i)[0]


def field_rows(run_folder, ref_folder, comm, padding=None):
    """Rows ``t, err_L2, err_H1, norm_L2, norm_H1`` (the FieldErrors columns, the reference's norms)
    at every time the run and the reference both stored (collective), and ``u_scale``: the
    reference's max_n ||u(t_n)||_L2 / sqrt(|Omega|) (a displacement: what "zero" is measured against).

    Args:
        padding: how far outside the reference mesh a point of the run's mesh may lie (a curved
            boundary that the two meshes approximate differently); default 1e-3 x the reference
            mesh's extent.
    """
    run, ref = _Stored(run_folder, comm), _Stored(ref_folder, comm)
    if padding is None:
        x = ref.W.mesh.geometry.x
        extent = comm.allreduce(float(np.ptp(x, axis=0).max()) if len(x) else 0.0, op=MPI.MAX)
        padding = 1e-3 * extent
    rows = []
    e = fem.Function(ref.W)
    for i, t in enumerate(run.reader.t):
        j = np.flatnonzero(np.abs(ref.reader.t - t) <= SAME_TIME * max(abs(t), 1.0))
        if not j.size:
            continue
        u_ref = ref.at(int(j[-1]))
        post.interpolate_nonmatching(e, run.at(i), padding=padding)
        e.x.array[:] -= u_ref.x.array
        rows.append((t, _l2(e, comm), post.h1_norm(e), _l2(u_ref, comm), post.h1_norm(u_ref)))
    a = np.array(rows, dtype=float).reshape(-1, 5)
    out = {c: a[:, k] for k, c in enumerate(("t", "err_L2", "err_H1", "norm_L2", "norm_H1"))}
    measure = cm.domain_measure(ref.W.mesh, comm)
    out["u_scale"] = float(np.max(out["norm_L2"])) / math.sqrt(measure) if len(a) and measure > 0 else None
    return out


def _l2(u, comm):
    """||u||_{L^2}, reduced over the ranks."""
    return math.sqrt(max(comm.allreduce(fem.assemble_scalar(compat.form(ufl.inner(u, u) * ufl.dx)), op=MPI.SUM),
                         0.0))
