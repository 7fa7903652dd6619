"""PETSc SNES ``vinewtonrsls`` (or ``vinewtonssls``) on the step LCP, for comparison with the
semi-smooth Newton (:mod:`sdm_dolfinx.solvers.semismooth`)."""
from collections.abc import Mapping
from typing import Any, Optional

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.factorisation import MUMPS_ICNTL14
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, snes_reason_name, vi_tolerances

#: vinewtonssls solves for x / s with s = SSLS_UNIT x (its tolerance in units of x): see SnesVI.solve
SSLS_UNIT = 1e2


class SnesVI:
    """PETSc SNES ``vinewtonrsls`` or ``vinewtonssls`` on the step LCP (bounds via
    ``setVariableBounds``).

    SNES gets its own Jacobian matrix J, reset to the step matrix K at every Jacobian
    evaluation: ``vinewtonssls`` turns J in place into the semi-smooth Jacobian of the
    Fischer-Burmeister function, D_a + D_b J (rows scaled, diagonal shifted), which would
    otherwise overwrite K (the integrator's step matrix) and accumulate over iterations.
    That matrix is not symmetric, so ``vinewtonssls`` factorises it by LU. Tolerances are
    relative to the right-hand side: an absolute 1e-12 stalls at round-off (STYLE pitfall).
    ``vinewtonrsls`` is known to cycle on P2/P1 at the first impact. ``vinewtonssls`` with
    the scalings of :meth:`solve` and a full step (``basic`` line search) follows the
    semi-smooth Newton's time series (membrane N = 8, 300 steps through the first impact:
    1e-7 to 3e-7 of each column's scale, the same active sets; ~3 iterations per step, at
    most 8, against ~1 for the semi-smooth Newton; tests/cli/test_vi_solvers.py). ``prefix`` and ``options`` as for
    :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton` (``-sdm_snes_*``,
    ``-sdm_ksp_*``, ``-sdm_pc_*`` apply).
    """

    def __init__(self, K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, symmetric_positive: bool = True,
                 snes_type: str = "vinewtonrsls", prefix: Optional[str] = None,
                 options: Optional[Mapping[str, Any]] = None, rtol: float = 1e-10, max_it: int = 60) -> None:
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb)
        self.prefix = instance_prefix(self.comm, prefix)
        with scoped_options(self.prefix, options, inherit=True) as scope:
            rtol, max_it, monitor = vi_tolerances(scope, rtol, max_it)
        self.rtol = rtol
        self.lam = np.zeros(len(self.cdofs))
        self.total_linear_its = 0
        # SNES solves F(x) = (K x - b) / r: F in units of x (r: the mean diagonal of K at the
        # constrained dofs, the Alart-Curnier parameter of the semi-smooth Newton), so that
        # the Fischer-Burmeister function of vinewtonssls, phi(x - lb, F), weighs the gap and
        # the force alike; vinewtonrsls is invariant under this scaling
        diag = K.getDiagonal()
        nc = self.comm.allreduce(len(self.cdofs), op=MPI.SUM)
        dsum = self.comm.allreduce(float(np.sum(diag.array[self.cdofs])), op=MPI.SUM)
        diag.destroy()
        self.r = dsum / nc if nc and dsum > 0 else 1.0
        self.s = 1.0
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(self.prefix)
        snes.setType(snes_type)
        snes.setTolerances(max_it=max_it)
        ksp = snes.getKSP()
        ksp.setType("preonly")
        # the semi-smooth Jacobian D_a + D_b K of vinewtonssls is not symmetric
        cholesky = symmetric_positive and snes_type != "vinewtonssls"
        ksp.getPC().setType("cholesky" if cholesky else "lu")
        ksp.getPC().setFactorSolverType("mumps")
        self.F = K.createVecLeft()
        self._b = None
        snes.setFunction(self._residual, self.F)
        self.J = K.duplicate(copy=True)    # SNES's own: vinewtonssls writes into its Jacobian
        snes.setJacobian(self._jacobian, self.J, self.J)
        xl, xu = K.createVecRight(), K.createVecRight()
        xl.set(PETSc.NINFINITY)
        xu.set(PETSc.INFINITY)
        xl.array[self.cdofs] = self.lb
        self.xl, self.xu = xl, xu
        snes.setVariableBounds(xl, xu)
        # a piecewise-linear VI wants a full step (petsc4py 3.18 has no getLineSearch)
        self.options = {"snes_linesearch_type": "basic", **({"snes_monitor": ""} if monitor else {}),
                        **(options or {})}
        try:
            with self.options_scope():
                snes.setFromOptions()
            max_it = snes.getTolerances()[3]
        except PETSc.Error:                # PETSc >= 3.20 refuses a negative max_it itself
            max_it = -1
        if max_it < 1:                     # SNES would stop before its first iteration
            for o in (snes, self.J, self.F, xl, xu):
                o.destroy()
            opts, key = PETSc.Options(), f"{self.prefix}snes_max_it"
            value = opts.getString(key) if opts.hasName(key) else self.options.get("snes_max_it", max_it)
            raise VIError(f"-{self.prefix}snes_max_it (or -sdm_snes_max_it): {value} is not an integer >= 1")
        self.snes = snes
        self.work = K.createVecRight()

    def options_scope(self):
        """This instance's options in the database (its ``options``, the shared ``-sdm_``
        ones) for the PETSc calls that read them."""
        return scoped_options(self.prefix, self.options, inherit=True)

    def _residual(self, snes, y, F):
        # F(y) = (K s y - b) / (r s): the LCP's residual in the solver's unit s of x (below)
        self.K.mult(y, F)
        F.axpy(-1.0 / self.s, self._b)
        F.scale(1.0 / self.r)

    def _jacobian(self, snes, y, J, P):
        # K / r, unchanged: F is linear (vinewtonssls scales and shifts J after this call,
        # so it is reset every time)
        self.K.copy(J, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        J.scale(1.0 / self.r)

    def solve(self, b, x):
        self._b = b
        # the tolerance in units of x: |F| / r <= rtol max|b| / r
        tol = self.rtol * max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300) / self.r
        # vinewtonssls takes the derivative of the Fischer-Burmeister function phi(a, b) as
        # (1/2, 1/2) wherever |a| and |b| are both below 1e-6 (PETSc's fixed threshold): at a
        # grazing contact (gap and force both ~0, as at the first impact) that wrong derivative
        # makes Newton converge linearly, thousands of iterations. Solving for y = x / s with
        # s = SSLS_UNIT x tol puts that threshold 1e4 times below the tolerance; rsls is left
        # in x (its active-set test uses an absolute 1e-8 on x - lb)
        self.s = SSLS_UNIT * tol if self.snes.getType() == "vinewtonssls" else 1.0
        self.xl.array[self.cdofs] = self.lb / self.s
        self.snes.setTolerances(atol=tol / self.s, rtol=self.rtol, stol=0.0)
        x.copy(self.work)                  # SNES solves into its own work vector
        self.work.scale(1.0 / self.s)
        # MUMPS reads its options when SNES factorises the Jacobian, viewers at the end
        with self.options_scope(), scoped_options(self.prefix, {"mat_mumps_icntl_14": str(MUMPS_ICNTL14)}):
            self.snes.solve(None, self.work)
        reason = self.snes.getConvergedReason()
        if reason <= 0:
            raise VIError(f"SNES {self.snes.getType()} diverged (reason {reason}: "
                          f"{snes_reason_name(reason)})")
        self.work.copy(x)
        x.scale(self.s)
        self.K.mult(x, self.F)
        self.F.axpy(-1.0, b)
        gap = x.array[self.cdofs] - self.lb
        tol_x = self.rtol * max(1.0, float(np.max(np.abs(self.lb), initial=0.0)))
        active = gap <= tol_x
        self.lam = np.where(active, self.F.array[self.cdofs], 0.0)
        self.total_linear_its += self.snes.getLinearSolveIterations()
        n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
        return {"its": self.snes.getIterationNumber(), "n_active": n_active}

    def destroy(self):
        self.snes.destroy()
        self.J.destroy()
