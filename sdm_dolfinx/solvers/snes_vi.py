"""PETSc SNES ``vinewtonrsls`` (or ``vinewtonssls``) on the step LCP, for comparison with the
semi-smooth Newton (:mod:`sdm_dolfinx.solvers.semismooth`)."""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.factorisation import MUMPS_ICNTL14
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, snes_reason_name, vi_tolerances


class SnesVI:
    """PETSc SNES ``vinewtonrsls`` on the step LCP (bounds via ``setVariableBounds``).

    Tolerances are relative to the right-hand side: an absolute 1e-12 stalls at round-off
    (STYLE pitfall). Known to cycle on P2/P1 at the first impact; kept for comparison.
    ``prefix`` and ``options`` as for :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton`
    (``-sdm_snes_*``, ``-sdm_ksp_*``, ``-sdm_pc_*`` apply).
    """

    def __init__(self, K, cdofs, lb, symmetric_positive=True, snes_type="vinewtonrsls", prefix=None,
                 options=None, rtol=1e-10, max_it=60):
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb)
        self.prefix = instance_prefix(self.comm, prefix)
        with scoped_options(self.prefix, options, inherit=True) as scope:
            rtol, max_it, monitor = vi_tolerances(scope, rtol, max_it)
        self.rtol = rtol
        self.lam = np.zeros(len(self.cdofs))
        self.total_linear_its = 0
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(self.prefix)
        snes.setType(snes_type)
        snes.setTolerances(max_it=max_it)
        ksp = snes.getKSP()
        ksp.setType("preonly")
        ksp.getPC().setType("cholesky" if symmetric_positive else "lu")
        ksp.getPC().setFactorSolverType("mumps")
        self.F = K.createVecLeft()
        self._b = None
        snes.setFunction(self._residual, self.F)
        snes.setJacobian(self._jacobian, K, K)
        xl, xu = K.createVecRight(), K.createVecRight()
        xl.set(PETSc.NINFINITY)
        xu.set(PETSc.INFINITY)
        xl.array[self.cdofs] = self.lb
        self.xl, self.xu = xl, xu
        snes.setVariableBounds(xl, xu)
        # a piecewise-linear VI wants a full step (petsc4py 3.18 has no getLineSearch)
        self.options = {"snes_linesearch_type": "basic", **({"snes_monitor": ""} if monitor else {}),
                        **(options or {})}
        with self.options_scope():
            snes.setFromOptions()
        self.snes = snes
        self.work = K.createVecRight()

    def options_scope(self):
        """This instance's options in the database (its ``options``, the shared ``-sdm_``
        ones) for the PETSc calls that read them."""
        return scoped_options(self.prefix, self.options, inherit=True)

    def _residual(self, snes, x, F):
        self.K.mult(x, F)
        F.axpy(-1.0, self._b)

    def _jacobian(self, snes, x, J, P):
        return None

    def solve(self, b, x):
        self._b = b
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        self.snes.setTolerances(atol=self.rtol * scale, rtol=self.rtol, stol=0.0)
        x.copy(self.work)                  # SNES solves into its own work vector
        # MUMPS reads its options when SNES factorises the Jacobian, viewers at the end
        with self.options_scope(), scoped_options(self.prefix, {"mat_mumps_icntl_14": str(MUMPS_ICNTL14)}):
            self.snes.solve(None, self.work)
        reason = self.snes.getConvergedReason()
        if reason <= 0:
            raise VIError(f"SNES {self.snes.getType()} diverged (reason {reason}: "
                          f"{snes_reason_name(reason)})")
        self.work.copy(x)
        self._residual(None, x, self.F)
        gap = x.array[self.cdofs] - self.lb
        tol_x = self.rtol * max(1.0, float(np.max(np.abs(self.lb), initial=0.0)))
        active = gap <= tol_x
        self.lam = np.where(active, self.F.array[self.cdofs], 0.0)
        self.total_linear_its += self.snes.getLinearSolveIterations()
        n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
        return {"its": self.snes.getIterationNumber(), "n_active": n_active}

    def destroy(self):
        self.snes.destroy()
