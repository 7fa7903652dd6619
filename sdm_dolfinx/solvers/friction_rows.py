"""The frictional Newton systems on general rows: friction on the weighted gap (``constrain="weighted"``).

The frictional step solver (:mod:`.friction_newton`) imposes its conditions on a normal and one or two
tangential "unknowns" per contact vertex: dofs (the vertex constraint), a node's components in its frame
(obstacles: :mod:`.friction_system`'s frames), or here rows of a sparse matrix. The weighted gap's row i
averages the normal component over the facets around the vertex a_i against its hat function psi_i,

    y_(i,n) = G_i x = sum_j w_ij x_(j,c),      y_(i,t) = H_(i,t) x = sum_j w_ij x_(j,t),

(``sdm_dolfinx.method.weighted_rows``: w_ij = int psi_i phi_j ds / int psi_i ds over the face's nodes j,
c the constrained component, t a tangential one: the same weights on another component, so the slip
of a row is the weighted average of the face's slip around a_i and its multiplier a nodal force). With
R the matrix of all these rows, a condition's column is K^-1 R_k^T = sum_j w_kj K^-1 e_j, a combination
of the cached columns of the face's dofs (the :class:`~.friction_system.ColumnCache`, one column per
face dof, as the gap-row Newton caches them), and its rows at the unknowns are R K^-1 R_J^T. Everything
else is :class:`~.friction_system.FrictionSystem`'s: the same dense systems (2-D) and cone (3-D) on these
columns, and the reactions go back to the body as R^T r (one more solve at the end of the step).

In parallel a row may read dofs of other ranks: the matrix R of every rank's rows is kept on every rank
(a few nonzeros per row), each rank holds its own face dofs' rows of the cached columns, and R's products
with them are summed over the ranks (one reduction of a dense (unknowns x columns) block per system,
the size of the system that :class:`~.friction_system.FrictionSystem` gathers anyway).
"""
from mpi4py import MPI

import numpy as np
import scipy.sparse as sp

from sdm_dolfinx.solvers.friction_system import ColumnCache, FrictionSystem


def component_rows(G, component, k):
    """This rank's rows of G (entries on ``component``'s dofs; the assembled pattern's explicit zeros on
    the other components dropped) with the same weights on component ``k``'s dofs: a scipy CSR matrix
    (local rows, W's global dof ids as columns)."""
    indptr, indices, data = G.getValuesCSR()
    local = sp.csr_matrix((data, indices, indptr), shape=(G.getLocalSize()[0], G.getSize()[1]))
    local.eliminate_zeros()
    local.indices = (local.indices - component + k).astype(local.indices.dtype)
    return local


def rows_matrix(G, component, components, comm):
    """(R: every rank's rows (normal ``component``, then each of ``components``, per rank in rank order),
    a scipy CSR matrix with W's global dof ids as columns, on every rank; this rank's first row in it).
    ``G``: the PETSc matrix of the normal rows (this rank's rows, W's column layout, entries on the
    dofs of ``component`` only)."""
    mine = sp.vstack([component_rows(G, component, k) for k in (component, *components)], format="csr")
    parts = comm.allgather(mine)
    offset = sum(p.shape[0] for p in parts[:comm.rank])
    return sp.vstack(parts, format="csr"), offset


class RowSystem(FrictionSystem):
    """The Newton systems of one step on rows (see the module) of ``R`` (:func:`rows_matrix`: this rank's
    unknowns are its rows ``offset`` .. ``offset`` + k m, normal ones first).

    ``read``: the rows change from step to step (:meth:`set_matrix`; contact between bodies, whose rows
    follow the slave vertices' projections) but read only these global dofs (sorted): the columns are
    cached at them; ``R`` may then be None until the first :meth:`set_matrix`."""

    def __init__(self, K, R, offset, n_unknowns, fac, read=None):
        self.K, self.fac, self.comm = K, fac, K.getComm().tompi4py()
        r0, nloc = K.getOwnershipRange()[0], K.getLocalSize()[0]
        used = np.unique(R.tocsr().indices) if read is None else np.asarray(read, dtype=np.int64)
        self.fg = used[(used >= r0) & (used < r0 + nloc)].astype(np.int64)     # this rank's face dofs
        self.cdofs = (self.fg - r0).astype(np.int32)
        self.set_matrix(sp.csr_matrix((0, K.getSize()[1])) if R is None else R)
        self.rows = slice(offset, offset + n_unknowns)
        self.gc = np.arange(offset, offset + n_unknowns, dtype=np.int64)        # the unknowns' global ids
        self.cols = ColumnCache(fac, self.cdofs, nloc)
        self._x0, self._rhs = K.createVecRight(), K.createVecLeft()
        self.starts = 0
        self.Q = None

    def set_matrix(self, R):
        """The rows of the next steps (every rank's, as :func:`rows_matrix` orders them; with ``read``,
        entries on those dofs only)."""
        self.R = R.tocsr()
        self.Rmine = self.R[:, self.fg].tocsc()                                # R at this rank's face dofs

    def _sum(self, local):
        out = np.empty_like(local)
        self.comm.Allreduce(np.ascontiguousarray(local), out, op=MPI.SUM)
        return out

    def values(self, u):
        """R u at this rank's unknowns (``u``: an owned array of W; collective)."""
        return self._sum(self.Rmine @ np.asarray(u)[self.cdofs])[self.rows]

    def start(self, b):
        """x0 = K^-1 b, once per step, and its values at the unknowns."""
        self.fac.solve(b, self._x0)
        self.starts += 1
        self._x0c = self.values(self._x0.array_r)

    def impose(self, xa, active, lb, stick, xref):
        """Nothing: a row's value is a combination of several dofs (its condition holds to round-off)."""

    def _columns(self, *masks):
        """For each mask of this rank's unknowns: (their global ids, gathered; this rank's offset among
        them; R K^-1 R_J^T at this rank's unknowns). The face dofs' columns not cached yet are solved in
        one batch (collective)."""
        parts = [self._gather(self.gc[mask]) for mask in masks]
        rows = [self.R[J] for J, _ in parts]
        support = np.unique(np.concatenate([r.indices for r in rows])).astype(np.int64) if rows else np.zeros(0)
        self.cols.ensure(support)
        Zs = self.cols.Zc[:, self.cols.slots(support)]           # this rank's face dofs x the support
        out = []
        for (J, off), RJ in zip(parts, rows):
            X = Zs @ RJ[:, support].T.toarray()                  # K^-1 R_J^T at this rank's face dofs
            out.append((J, off, self._sum(self.Rmine @ X)[self.rows]))
        return out

    def finish(self, b, x):
        """x = K^-1 (b + R^T r) for the reactions r of the last system (one more solve)."""
        r, _ = self._gather(self._last)
        b.copy(self._rhs)
        self._rhs.array[self.cdofs] += self.Rmine.T @ r
        self.fac.solve(self._rhs, x)
        self.starts += 1


class RowColumns:
    """What a restart replays of a :class:`RowSystem`'s cached columns (``_ensure_columns``: they are
    columns of W's dofs, recorded by each dof's coordinates and component: ``run.solver_state``)."""

    def __init__(self, system):
        self.system = system

    def _ensure_columns(self, gids):
        self.system.cols.ensure(np.asarray(gids, dtype=np.int64))
