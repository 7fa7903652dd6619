"""The node frames of the static problem against obstacles (``u0 = "equilibrium"``,
:mod:`sdm_dolfinx.method.equilibrium`): U = T Y, at each constrained node U_i = Q_i^T Y_i with Q_i
orthonormal and its row ``constraint_component`` the nearest obstacle's normal at the reference node
(t = 0), so that each node's row n_i . U_i >= -phi(a_i) is the bound of one unknown Y_c."""
import numpy as np

from sdm_dolfinx.solvers.friction_frames import at_component, frames_of, from_frame, rotation, to_frame


class ObstacleFrame:
    """The rotation U = T Y of the static problem against obstacles (the module): at each constrained
    node the orthonormal Q_i whose row ``constraint_component`` is the nearest obstacle's normal at the
    reference node a_i (t = 0), the identity elsewhere. ``A`` = T^T A T, ``lb`` = -phi(a_i) (the bound
    of Y at the constrained dofs), ``mass_mult`` = T^T M T."""

    def __init__(self, d):
        rows, comp = d.obstacle_rows, d.problem.constraint_component or 0
        rows.require_free("u0 = 'equilibrium' against obstacles")
        self.d, self.dofs, k = d, rows.dofs, rows.gdim
        phi, normals = rows.reference()
        Q = frames_of(normals) if len(phi) else np.zeros((0, k, k))
        self.Q = at_component(Q, comp)
        self.lb = -phi
        A = d.A
        T = rotation(A, self.dofs, self.Q)
        self.A = A.PtAP(T)
        T.destroy()
        self._tmp = A.createVecLeft()

    def to_frame_rows(self, X):
        """T^T X for owned rows X (n x j), a copy."""
        return to_frame(np.array(X, copy=True), self.dofs, self.Q)

    def to_frame(self, v):
        """v := T^T v (a PETSc vector of W)."""
        to_frame(v.array, self.dofs, self.Q)

    def from_frame(self, v):
        """v := T v."""
        from_frame(v.array, self.dofs, self.Q)

    def start(self, L):
        """(A, lb, mass_mult) of the static problem in the frame; L := T^T L in place."""
        self.to_frame(L)
        return self.A, self.lb, self.mass_mult

    def mass_mult(self, x, y):
        """y = T^T M T x."""
        x.copy(self._tmp)
        self.from_frame(self._tmp)
        self.d.mass_mult(self._tmp, y)
        self.to_frame(y)

    def destroy(self):
        self.A.destroy()
        self._tmp.destroy()
