"""The semi-smooth Newton on general gap rows: G x >= g.

Each step of the midpoint or backward Euler scheme with gap rows is the variational inequality

    G x >= g,   lam >= 0,   lam . (G x - g) = 0,   K x - b = G^T lam,

row i of G a linear functional of the displacement: against a rigid obstacle it reads the k = gdim
dofs of one node, G_i x = n_i . x_node (n_i the obstacle's unit normal there, so that G_i^T lam_i is
the force lam_i n_i on that node: :class:`~.gap_rows.NodeRows`, its coefficients given anew before every step);
a weighted (mortar) gap reads every dof of the contact facets around a vertex (:class:`~.gap_rows.MatrixRows`,
a distributed PETSc matrix fixed for the run). The axis-aligned bound x_c >= lb of
:class:`~.semismooth.SemismoothNewton` is the node row n_i = e_c.

As in its ``schur`` strategy, K is factorised once per run and the Newton systems are dense: with
x0 = K^-1 b (one solve per step) and the columns K^-1 e_j cached for every dof j an active row has
ever read (a node row whose normal turns costs no new solve), a Newton system on the active set A is
x = x0 + K^-1 G_A^T mu, with mu from the |A| x |A| SPD system

    (G_A K^-1 G_A^T) mu = g_A - G_A x0,

and mu is the multiplier. The active set is updated as in the primal-dual active set method
(Murty's rule against cycles).

**Krylov fallback.** When an active set needs more than ``max_columns`` cached columns (an active
zone of about max_columns / gdim nodes against an obstacle, fewer with weighted rows: a 3-D contact
zone at a fine level), the system is solved by conjugate gradients on the Schur complement instead,
each product S v = G_A K^-1 G_A^T v one solve with the factorisation (S is SPD for SPD K and rows of
full rank: the M formulation; not built for the (U, V) block variant, refused there), then
x = x0 + K^-1 G_A^T mu by one more solve. The columns already cached stay for the smaller active sets.
CG stops at a residual of :data:`~.gap_krylov.KRYLOV_RTOL` times the right-hand side's.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional, Union

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.gap_rows import MatrixRows, NodeRows, SurfaceRows
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, vi_tolerances
from sdm_dolfinx.solvers.schur import SCHUR_MAX_COLUMNS

Array = npt.NDArray[np.float64]


class GapNewton:
    """Primal-dual active set solver for the step VI with gap rows (see the module).

    Args:
        K: the step matrix (Dirichlet rows are identity rows).
        dofs: node rows: (m, k) owned local indices of x that each of this rank's m rows reads
            (coefficients and g given before each solve by :meth:`set_rows`); or None with ``G``.
        G: matrix rows: a PETSc matrix (this rank's rows, K's columns) fixed for the run (g by
            :meth:`set_rows` ``(None, g)``); or None.
        surface: surface rows (``(read, m)``: the global dofs any row may read, this rank's number of
            rows; ids, coefficients and g by :meth:`set_rows` ``((ids, coef), g)``); or None.
        symmetric_positive: K is SPD (M formulation); else the (U, V) block matrix.
        prefix: PETSc options prefix (None: a new ``sdm_<k>_``); ``vi_rtol``, ``vi_max_it``,
            ``vi_monitor`` as for the semi-smooth Newton (:func:`vi_tolerances`).
        options: default PETSc options of this instance.
        factor_matrix: a sparser matrix whose factorisation solves with K, or None.
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
        max_columns: the most columns K^-1 e_j cached (the largest active zone solved on them; beyond,
            the Krylov fallback); the option ``-<prefix>gap_max_columns`` overrides it.
        stiffness: a penalty instead of the exact contact: the rows' spring stiffnesses k (m,), the
            force lam = k (g - G x)_+ (:mod:`sdm_dolfinx.contact.penalty`); each Newton system is
            then (G_A K^-1 G_A^T + diag(1/k_A)) mu = g_A - G_A x0, as for the unit rows'
            :class:`~sdm_dolfinx.solvers.penalty.PenaltyNewton`.

    ``lam`` (m,) and ``active`` (m,) are those of the last solve; ``g`` the rows' right-hand sides.
    """

    def __init__(self, K: PETSc.Mat, dofs: Optional[npt.ArrayLike] = None, symmetric_positive: bool = True,
                 prefix: Optional[str] = None, options: Optional[Mapping[str, Any]] = None,
                 factor_matrix: Optional[PETSc.Mat] = None, rtol: float = 1e-10, max_it: int = 500,
                 max_columns: int = SCHUR_MAX_COLUMNS, G: Optional[PETSc.Mat] = None,
                 stiffness: Optional[npt.ArrayLike] = None, surface: Optional[tuple[Any, int]] = None) -> None:
        if sum(a is not None for a in (dofs, G, surface)) != 1:
            raise ValueError("GapNewton takes node rows (dofs), a matrix G or surface rows (read, m), one of them")
        self.K, self.comm = K, K.getComm().tompi4py()
        self.prefix, self.options = instance_prefix(self.comm, prefix), dict(options or {})
        self.spd, self.linear = symmetric_positive, "schur"
        with scoped_options(self.prefix, self.options, inherit=True) as scope:
            self.rtol, self.max_it, self.monitor = vi_tolerances(scope, rtol, max_it)
            # -<prefix>gap_max_columns N: the most columns of K^-1 cached (beyond: the Krylov fallback)
            max_columns = PETSc.Options().getInt(scope.prefix + "gap_max_columns", max_columns)
            if max_columns < 0:
                raise VIError(f"-{self.prefix}gap_max_columns (or -sdm_gap_max_columns): {max_columns} is not an "
                              f"integer >= 0")
            self.fac = Factorisation(K, symmetric_positive, self.prefix + "factor_", aug=factor_matrix)
        self.rows: Union[NodeRows, MatrixRows, SurfaceRows]
        if dofs is not None:
            self.rows = NodeRows(K, self.fac, dofs, max_columns)
        elif G is not None:
            self.rows = MatrixRows(K, self.fac, G, max_columns)
        else:
            assert surface is not None
            self.rows = SurfaceRows(K, self.fac, *surface, max_columns)
        self.rows.spd = bool(symmetric_positive)
        m = len(self.rows.g)
        if stiffness is not None:
            k = np.broadcast_to(np.asarray(stiffness, dtype=float), (m,))
            if not self.comm.allreduce(bool(np.all(np.isfinite(k) & (k > 0.0))), op=MPI.LAND):
                raise ValueError("the penalty's stiffnesses must be finite and > 0")
            self.rows.compliance = 1.0 / k
        self.num_constraints = self.comm.allreduce(m, op=MPI.SUM)
        self.lam, self.active = np.zeros(m), np.zeros(m, dtype=bool)
        # the Alart–Curnier scale r: the mean of K's diagonal at the dofs the rows read
        diag = K.getDiagonal()
        if isinstance(self.rows, NodeRows):
            read = self.rows.dofs.reshape(-1)
        elif isinstance(self.rows, SurfaceRows):
            read = self.rows._local
        else:
            read = np.unique(self.rows._aj) - K.getOwnershipRange()[0]
            read = read[(read >= 0) & (read < K.getLocalSize()[0])]
        dsum = self.comm.allreduce(float(np.sum(diag.array[read])), op=MPI.SUM)
        nread = self.comm.allreduce(len(read), op=MPI.SUM)
        self.r = dsum / nread if nread else 1.0
        diag.destroy()
        self._x0 = K.createVecRight()

    @property
    def g(self) -> Array:
        return self.rows.g

    @property
    def total_linear_its(self) -> int:
        """Solves with the factorisation so far (one per step, one per new column)."""
        return self.rows.its

    def set_rows(self, coef: Optional[npt.ArrayLike], g: npt.ArrayLike) -> None:
        """The rows of the next solve: node rows G_i x = coef[i] . x[dofs[i]] >= g[i]; matrix rows
        (coef None) G_i x >= g[i]."""
        if isinstance(self.rows, (NodeRows, SurfaceRows)):
            self.rows.set(coef, g)
        else:
            self.rows.set(g)

    def row_values(self, x: Array) -> Array:
        """G x at this rank's rows for the owned array ``x`` (collective for matrix rows)."""
        return self.rows.values(x)

    def imposed_gap(self, x: Array) -> float:
        """min over this rank's rows of G x - g (collective for matrix rows: every rank calls it)."""
        return float(np.min(self.row_values(x) - self.g, initial=np.inf))

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> dict[str, Any]:
        """Solve the step VI for the right-hand side b into x (see the module); returns
        ``{"its", "n_active"}``. Raises VIError (no convergence, a contact zone too large)."""
        rows = self.rows
        with scoped_options(self.prefix, self.options, inherit=True):
            self.fac.solve(b, self._x0)
        rows.its += 1
        rows.start(self._x0)
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        tol_lam = self.rtol * scale
        tol_x = tol_lam / self.r
        active = self.active.copy() & getattr(rows, "alive", True)      # a row without coefficients holds nothing
        first = self.comm.exscan(len(rows.g)) or 0
        murty = MurtyRule(first + np.arange(len(rows.g)), self.comm)
        for it in range(1, self.max_it + 1):
            gx, lam = rows.system(active)
            lam = np.where(active, lam, 0.0)
            infeasible = np.where(active, lam < -tol_lam, gx < rows.g - tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            if self.monitor:
                n_act = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                if self.comm.rank == 0:
                    print(f"  {it:3d} semi-smooth Newton (gap rows): {n_act} active, {n_inf} infeasible", flush=True)
            if n_inf == 0:
                rows.finish(b, x)
                return {"its": it, "n_active": self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)}
            one = murty.single(n_inf, infeasible)
            active = active ^ (infeasible if one is None else one)
        raise VIError(f"semi-smooth Newton (gap rows) did not converge in {self.max_it} iterations "
                      f"({n_inf} rows still infeasible)")

    def destroy(self) -> None:
        self._x0.destroy()
        self.rows.destroy()
        self.fac.destroy()
