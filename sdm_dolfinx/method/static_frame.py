"""The node frames of the static problem against obstacles (``u0 = "equilibrium"``,
:mod:`sdm_dolfinx.method.equilibrium`): U = T Y, at each constrained node U_i = Q_i^T Y_i with Q_i
orthonormal and its row ``constraint_component`` the nearest obstacle's normal at the reference node
(t = 0), so that each node's row n_i . U_i >= -phi(a_i) is the bound of one unknown Y_c."""
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method.obstacle_rows import nearest
from sdm_dolfinx.solvers.friction_frames import frames_of


class ObstacleFrame:
    """The rotation U = T Y of the static problem against obstacles (the module): at each constrained
    node the orthonormal Q_i whose row ``constraint_component`` is the nearest obstacle's normal at the
    reference node a_i (t = 0), the identity elsewhere. ``A`` = T^T A T, ``lb`` = -phi(a_i) (the bound
    of Y at the constrained dofs), ``mass_mult`` = T^T M T."""

    def __init__(self, d):
        rows, comp = d.obstacle_rows, d.problem.constraint_component or 0
        self.d, self.dofs, k = d, rows.dofs, rows.gdim
        phi, nrm, _ = nearest(rows.obstacles, rows.x, 0.0)
        Q = frames_of(np.ascontiguousarray(nrm[:k].T)) if len(phi) else np.zeros((0, k, k))
        self.Q = np.empty_like(Q)                         # the normal at row comp, the tangents around it
        self.Q[:, comp] = Q[:, 0]
        for j, c in enumerate(c for c in range(k) if c != comp):
            self.Q[:, c] = Q[:, 1 + j]
        self.lb = -phi
        A = d.A
        r0, nloc = A.getOwnershipRange()[0], A.getLocalSize()[0]
        T = PETSc.Mat().createAIJ(A.getSizes(), nnz=k, comm=A.getComm())
        off = np.ones(nloc, dtype=bool)
        off[self.dofs.reshape(-1)] = False
        for i in np.flatnonzero(off):
            T.setValue(r0 + i, r0 + i, 1.0)
        for i in range(len(self.dofs)):                   # U_c = sum_k Q_kc Y_k at the node's dofs
            g = (r0 + self.dofs[i]).astype(PETSc.IntType)
            T.setValues(g, g, np.ascontiguousarray(self.Q[i].T, dtype=PETSc.ScalarType))
        T.assemble()
        self.A = A.PtAP(T)
        T.destroy()
        self._tmp = A.createVecLeft()

    def to_frame_rows(self, X):
        """T^T X for owned rows X (n x j)."""
        Y = np.array(X, copy=True)
        if len(self.dofs):
            Y[self.dofs] = np.einsum("ikc,icj->ikj", self.Q, X[self.dofs])
        return Y

    def to_frame(self, v):
        """v := T^T v (a PETSc vector of W)."""
        a = v.array
        if len(self.dofs):
            a[self.dofs] = np.einsum("ikc,ic->ik", self.Q, a[self.dofs])

    def from_frame(self, v):
        """v := T v."""
        a = v.array
        if len(self.dofs):
            a[self.dofs] = np.einsum("ikc,ik->ic", self.Q, a[self.dofs])

    def start(self, L):
        """(A, lb, mass_mult) of the static problem in the frame; L := T^T L in place."""
        self.to_frame(L)
        return self.A, self.lb, self.mass_mult

    def finish(self, U):
        """U := T U (the static solution, back from the frame); frees the frame's matrix."""
        self.from_frame(U)
        self.destroy()

    def mass_mult(self, x, y):
        """y = T^T M T x."""
        x.copy(self._tmp)
        self.from_frame(self._tmp)
        self.d.mass_mult(self._tmp, y)
        self.to_frame(y)

    def destroy(self):
        self.A.destroy()
        self._tmp.destroy()
