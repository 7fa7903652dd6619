"""PETSc's SNES VI on node gap rows (rigid obstacles): n_i . x_i >= g_i, through a change of variables.

SNES VI bounds single unknowns (``setVariableBounds``), and a node row bounds a combination of a node's
Cartesian dofs. So each step is solved in the nodes' frames: x = T y with U_i = Q_i^T Y_i at each
constrained node (Q_i orthonormal, its row ``comp`` the row's normal n_i, the others the tangents of
:func:`~sdm_dolfinx.solvers.friction_frames.frames_of`), the identity elsewhere. Then n_i . x_i = y_(i,
comp), and the step's LCP K x = b + G^T lam, G x >= g is, with K_Y = T^T K T (SPD when K is) and
b_Y = T^T b, the bound-constrained LCP K_Y y = b_Y + lam, y_(i, comp) >= g_i of
:class:`~sdm_dolfinx.solvers.snes_vi.SnesVI`. The frames turn with the normals: T and K_Y are rebuilt
before every step (a sparse triple product, K_Y's pattern is K's: T is block-diagonal within nodes),
and SNES factorises K_Y at each of its iterations as it does K. A comparison solver, as for the unit
rows: the semi-smooth Newton (:mod:`~sdm_dolfinx.solvers.gap_newton`) factorises once per run.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional

from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.friction_frames import at_component, frames_of, from_frame, rotation, to_frame
from sdm_dolfinx.solvers.snes_vi import SnesVI


class FramedSnesVI:
    """:class:`SnesVI` on node rows (see the module).

    Args:
        K: the step matrix.
        dofs: (m, k) owned local dofs of this rank's m constrained nodes (row i reads dofs[i]).
        comp: which of a node's k unknowns in its frame is the normal one (the problem's
            ``constraint_component``: the bounded unknowns are then ``dofs[:, comp]``).
        snes_type, symmetric_positive, prefix, options: as for :class:`SnesVI`.

    ``lam`` and ``active`` (m,) are those of the last solve; :meth:`set_rows` gives the normals and
    bounds before each solve.
    """

    def __init__(self, K: PETSc.Mat, dofs: npt.ArrayLike, comp: int, snes_type: str = "vinewtonrsls",
                 symmetric_positive: bool = True, prefix: Optional[str] = None,
                 options: Optional[Mapping[str, Any]] = None) -> None:
        self.K = K
        self.dofs = np.asarray(dofs, dtype=np.int32)
        m, k = self.dofs.shape
        self.comp = int(comp)
        self.Q = at_component(frames_of(np.tile(np.eye(k)[comp], (m, 1))), comp)
        self.g = np.zeros(m)
        self.T = rotation(K, self.dofs, self.Q)
        self.KY = K.PtAP(self.T)
        self.inner = SnesVI(self.KY, self.dofs[:, self.comp], self.g, symmetric_positive=symmetric_positive,
                            snes_type=snes_type, prefix=prefix, options=options)
        self._bY, self._xY = self.KY.createVecLeft(), self.KY.createVecRight()
        self.lam, self.active = np.zeros(m), np.zeros(m, dtype=bool)

    @property
    def total_linear_its(self) -> int:
        return int(self.inner.total_linear_its)

    def set_rows(self, coef: npt.ArrayLike, g: npt.ArrayLike) -> None:
        """The rows n_i . x_i >= g_i of the next solve (``coef``: the unit normals, m x k)."""
        m, k = self.dofs.shape
        n = np.asarray(coef, dtype=float).reshape(m, k)
        self.Q = at_component(frames_of(n), self.comp)
        self.g[:] = np.asarray(g, dtype=float).reshape(m)
        self.inner.lb = self.g
        rotation(self.K, self.dofs, self.Q, self.T)
        self.K.PtAP(self.T, result=self.KY)

    def row_values(self, x: np.ndarray) -> np.ndarray:
        """n_i . x_i at this rank's rows for the owned array ``x``."""
        return np.einsum("ik,ik->i", self.Q[:, self.comp], x[self.dofs]) if len(self.g) else np.zeros(0)

    def imposed_gap(self, x: np.ndarray) -> float:
        """min over this rank's rows of n_i . x_i - g_i (+inf without rows)."""
        return float(np.min(self.row_values(x) - self.g, initial=np.inf))

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> dict[str, Any]:
        """Solve the step for the right-hand side b into x (x holds the initial guess)."""
        b.copy(self._bY)
        to_frame(self._bY.array, self.dofs, self.Q)
        x.copy(self._xY)
        to_frame(self._xY.array, self.dofs, self.Q)
        info = self.inner.solve(self._bY, self._xY)
        self._xY.copy(x)
        from_frame(x.array, self.dofs, self.Q)
        self.lam = np.asarray(self.inner.lam, dtype=float)
        self.active = self.lam > 0.0
        return info

    def destroy(self) -> None:
        self.inner.destroy()
        for o in (self.T, self.KY, self._bY, self._xY):
            o.destroy()
