"""The per-body and per-pair columns of a run whose Problem declares ``bodies`` or ``contact_pairs``.

Per body b (:mod:`sdm_dolfinx.problems.bodies`): ``momentum_<b>_<axis>`` = e_b^T M Vbar, e_b the unit
translation of body b along the axis (zero off its dofs), ``kinetic_<b>`` = 1/2 Vbar_b^T M Vbar_b and
``elastic_<b>`` = 1/2 U_b^T A U_b, with U_b, Vbar_b the fields restricted to the body's dofs. Bodies share
no dof (refused otherwise), so M and A are block diagonal over them: the bodies' kinetic and elastic
energies and momenta add up to the run's (``kinetic`` and ``elastic`` without a load, ``momentum_x``...).
Per contact pair p: ``contact_force_<p>``, the sum of the multipliers of the slave vertices whose row
held them against p's master in the step (the run's ``contact_force`` is their sum).
"""
from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx import compat
from sdm_dolfinx.method.dofs import owned_size
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.problems.base import label

AXES = "xyz"


def columns(problem: Any) -> tuple[str, ...]:
    """The per-body and per-pair column names of ``problem`` (none without bodies or pairs)."""
    gdim = int(problem.shape[0]) if problem.shape else 1
    per_body = tuple(c for b in getattr(problem, "bodies", ()) for c in
                     [f"momentum_{b.name}_{AXES[k]}" for k in range(gdim)] + [f"kinetic_{b.name}", f"elastic_{b.name}"])
    return per_body + tuple(f"contact_force_{p.name}" for p in getattr(problem, "contact_pairs", ()))


class BodyColumns:
    """The values of :func:`columns` for a Discretisation ``d`` (collective)."""

    def __init__(self, d: Any) -> None:
        p, W = d.problem, d.W
        self.d, self.comm = d, d.comm
        if d.mass == "consistent":              # Vbar is not the velocity unknown there
            raise DiscretisationError(f"{label(p)}: the per-body columns are not built for mass 'consistent': use "
                                      f"mass 'lumped'")
        bs, n = W.dofmap.index_map_bs, owned_size(W)
        dofmap = compat.dofmap_list(W)
        self.masks = []
        count = np.zeros(n, dtype=np.int32)
        for b in getattr(p, "bodies", ()):
            cells = np.asarray(b.cells(p.mesh), dtype=np.int64).reshape(-1)
            blocks = np.unique(dofmap[cells]) if cells.size else np.zeros(0, dtype=np.int64)
            mask = np.zeros(n, dtype=bool)
            dofs = (blocks[:, None] * bs + np.arange(bs)).reshape(-1)
            mask[dofs[dofs < n]] = True
            self.masks.append((b.name, mask))
            count += mask
        shared = self.comm.allreduce(int(np.count_nonzero(count > 1)), op=MPI.SUM)
        if shared:
            raise DiscretisationError(f"{label(p)}: its bodies share {shared} dofs (a body's cells must not touch "
                                      f"another's)")
        self.gdim, self.bs = (int(p.shape[0]) if p.shape else 1), bs
        self.pairs = [pair.name for pair in getattr(p, "contact_pairs", ())]
        self._x, self._y = d.A.createVecRight(), d.A.createVecLeft()

    def _quad(self, mat_mult: Any, vec: Any, mask: npt.NDArray[np.bool_]) -> float:
        self._x.array[:] = np.where(mask, vec.array_r, 0.0)
        mat_mult(self._x, self._y)
        return 0.5 * self._x.dot(self._y)

    def values(self, U: Any, V: Any, lam: npt.NDArray[np.float64]) -> dict[str, float]:
        """The columns at the state (U, Vbar) with the step's multipliers ``lam`` (collective)."""
        d, out = self.d, {}
        for name, mask in self.masks:
            out[f"kinetic_{name}"] = self._quad(d.mass_mult, V, mask)
            out[f"elastic_{name}"] = self._quad(d.A.mult, U, mask)
            d.mass_mult(V, self._y)
            for k in range(self.gdim):
                sel = mask.copy()
                sel[np.arange(len(sel)) % self.bs != k] = False
                out[f"momentum_{name}_{AXES[k]}"] = self.comm.allreduce(float(np.sum(self._y.array_r[sel])),
                                                                      op=MPI.SUM)
        rows = getattr(d, "body_rows", None)
        which = rows.pair_of_row if rows is not None else np.zeros(0, dtype=np.int64)
        for k, name in enumerate(self.pairs):
            out[f"contact_force_{name}"] = self.comm.allreduce(
                float(np.sum(lam[which == k])) if len(lam) == len(which) else 0.0, op=MPI.SUM)
        return out

    def destroy(self) -> None:
        self._x.destroy(), self._y.destroy()
