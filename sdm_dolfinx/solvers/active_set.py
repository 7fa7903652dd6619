"""The linear systems of the semi-smooth Newton: K restricted to the inactive set.

A Newton step with active set A solves x_A = lb_A, (K x - b)_I = 0. :data:`LINEAR_STRATEGIES`
are the ways to solve it (see :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton`);
:class:`InactiveSetSolver` does all but the dense Schur complement
(:mod:`sdm_dolfinx.solvers.schur`), which falls back to it for large active sets.
"""
from typing import Optional

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.solvers import memory
from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.factorisation import mumps_margins
from sdm_dolfinx.solvers.options import ksp_reason_name, scoped_options

#: linear strategies of the semi-smooth Newton (see :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton`)
LINEAR_STRATEGIES = ("auto", "schur", "cg-factor", "lu", "amg", "cg-amg", "cg-gamg", "cg-pmg")

#: the strategies that precondition CG by a multigrid of K built once per run, with no factorisation
#: (:mod:`sdm_dolfinx.method.iterative` attaches what they need to K)
MULTIGRID_STRATEGIES = ("cg-gamg", "cg-pmg")

#: the strategies whose preconditioner is hypre's BoomerAMG
HYPRE_STRATEGIES = ("amg", "cg-amg")


def missing_package(linear: object) -> Optional[str]:
    """Why strategy ``linear`` cannot run when this PETSc lacks the package it needs (hypre for
    :data:`HYPRE_STRATEGIES`: the PyPI wheel dolfinx-solver-real has none), else None."""
    if linear in HYPRE_STRATEGIES and not compat.petsc_has("hypre"):
        return ("needs hypre's BoomerAMG, and this PETSc has no hypre: choose cg-gamg (PETSc's own "
                "algebraic multigrid), schur or cg-factor")
    return None


#: ``auto`` takes ``schur`` up to this many constrained dofs, ``amg`` beyond: many
#: constraints (the membrane, N_g ~ N^2) mean active sets of thousands in the impact phase,
#: where CG + BoomerAMG scales best (bench/README.md); in 3-D see :func:`choose_strategy`
SCHUR_MAX_CONSTRAINTS = 10000

#: the strategies that run a Krylov method on :class:`ReducedOperator` with :class:`ReducedPC`
SHELL_STRATEGIES = ("cg-factor", "cg-amg", "cg-gamg", "cg-pmg", "schur")

#: PETSc GAMG's default options for ``cg-gamg`` (``-<prefix>gamg_...`` overrides): smoothed
#: aggregation with the near-nullspace (the rigid body modes,
#: :func:`~sdm_dolfinx.method.iterative.rigid_body_modes`), Chebyshev/Jacobi smoothing (a fixed
#: linear preconditioner, as CG needs); other smoothing steps and thresholds measured within the
#: noise on the ball (bench/README.md)
GAMG_OPTIONS = {"pc_gamg_type": "agg", "pc_gamg_agg_nsmooths": "1", "pc_gamg_threshold": "0.01",
                "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi"}

#: ``cg-gamg`` builds GAMG on the matrix composed with K under PMAT (a sparse P ~ K) and applies
#: K as the Mat composed under PRODUCT, when there are
#: (:func:`sdm_dolfinx.method.iterative.attach`); otherwise on K and with K
PMAT, PRODUCT = "sdm_gamg_pmat", "sdm_fast_product"

#: ``cg-pmg``: a two-level P2 -> P1 multigrid of K, preconditioning CG; its interpolation I from the
#: vertices' P1 space into W^h and the Galerkin coarse operator I^T K I (with the rigid body modes) are
#: composed with K under these names (:func:`sdm_dolfinx.method.iterative.attach`)
PMG_INTERPOLATION, PMG_COARSE = "sdm_pmg_interpolation", "sdm_pmg_coarse"

#: ``cg-pmg``'s default options (``-<prefix>pmg_...`` overrides): one V-cycle, two Chebyshev/Jacobi
#: smoothing steps on K (its diagonal from the sparse P) before and after, GAMG on the coarse P1 operator
#: (:data:`GAMG_OPTIONS`). Measured on the ball (bench/README.md, "cg-pmg"): 17-19 CG iterations at
#: levels 1-4 where GAMG on P takes 43-69
PMG_OPTIONS = {"pc_mg_cycle_type": "v", "mg_levels_ksp_type": "chebyshev", "mg_levels_pc_type": "jacobi",
               "mg_levels_ksp_max_it": "2", "mg_coarse_ksp_type": "preonly", "mg_coarse_pc_type": "gamg",
               **{"mg_coarse_" + k: v for k, v in GAMG_OPTIONS.items()}}


def choose_strategy(num_constraints, spd, n=None, dim=2, comm=None, explain=False):
    """What ``linear="auto"`` means (``explain``: also the one-line reason).

    ``schur``, or ``amg`` for many constraints (SPD only; ``schur`` where PETSc has no hypre); in 3-D (``dim`` 3, ``n`` = dim W^h)
    ``cg-gamg`` when the factorised run's memory (:func:`~sdm_dolfinx.solvers.memory.run_bytes`,
    a fit of measured peak RSS) exceeds MEMORY_MARGIN of the memory available per rank
    (MemAvailable / ranks on the node): the iterative strategy is several times slower per step
    (bench/README.md) but needs no factor.
    """
    name = "schur" if num_constraints <= SCHUR_MAX_CONSTRAINTS or not spd else "amg"
    why = (f"{num_constraints} constrained dofs {'<=' if name == 'schur' else '>'} {SCHUR_MAX_CONSTRAINTS}"
           if spd else "K is not SPD")
    if name == "amg" and missing_package(name):
        name, why = "schur", f"{why}, but this PETSc has no hypre for amg"
    if spd and n is not None and dim >= 3 and name == "schur":      # in 2-D auto does not look at memory
        comm = comm or MPI.COMM_WORLD
        avail = memory.available_per_rank(comm)
        if avail is not None:
            fits, need = memory.factorisation_fits(n, dim, comm.size, avail)
            name = "schur" if fits else "cg-gamg"
            why = (f"a factorisation needs ~{need / 1e9:.2g} GB per rank, {avail / 1e9:.2g} GB available per rank"
                   f"{'' if fits else ': iterative'}")
    return (name, why) if explain else name


class ReducedOperator:
    """y = K_A x: K with the active rows and columns replaced by the identity."""

    def __init__(self, K, active_mask, product=None):
        self.K, self.mask = (product or K), active_mask
        self.tmp = K.createVecRight()

    def mult(self, mat, x, y):
        xa = x.getArray(readonly=True)
        self.tmp.array[:] = xa
        self.tmp.array[self.mask] = 0.0
        self.K.mult(self.tmp, y)
        y.array[self.mask] = xa[self.mask]


class ReducedPC:
    """z = P restricted to the inactive set (identity on the active set), P ~ K^-1.

    With P = K^-1 (one factorisation) this differs from (K_A)^-1 by a term of rank
    |active|, so Krylov converges in at most |active| + 1 iterations; with P one AMG cycle
    on K, the AMG set-up is done once per run.
    """

    def __init__(self, apply_P, active_mask, K):
        self.apply_P, self.mask = apply_P, active_mask
        self.tmp, self.z = K.createVecRight(), K.createVecLeft()

    def apply(self, pc, r, z):
        ra = r.getArray(readonly=True)
        self.tmp.array[:] = ra
        self.tmp.array[self.mask] = 0.0
        self.apply_P(self.tmp, self.z)
        z.array[:] = self.z.array_r
        z.array[self.mask] = ra[self.mask]


class InactiveSetSolver:
    """Newton systems x_A = lb_A, (K x - b)_I = 0 by a KSP (prefix ``prefix``).

    Args:
        K: the step matrix; cdofs, lb: the constrained entries and their bounds.
        spd: K is SPD -> CG; otherwise GMRES (or LU instead of Cholesky).
        linear: ``cg-factor``, ``schur`` (its Krylov fallback) or ``cg-amg``: CG / GMRES on
            :class:`ReducedOperator` preconditioned by :class:`ReducedPC` with ``fac`` or one
            BoomerAMG set-up of K; ``lu``: a MUMPS factorisation of the reduced matrix at
            every iteration; ``amg``: CG + BoomerAMG on the reduced matrix, set up again
            when the active set changed.
        fac: the :class:`~sdm_dolfinx.solvers.factorisation.Factorisation` of K
            (``schur``, ``cg-factor``).

    Build it inside the solver's options scope (it calls setFromOptions). ``its`` counts the
    linear iterations.
    """

    def __init__(self, K, cdofs, lb, spd, linear, prefix, fac=None):
        self.K, self.cdofs, self.lb, self.spd, self.linear, self.prefix = K, cdofs, lb, spd, linear, prefix
        self.comm = K.getComm().tompi4py()
        self.fac = fac
        self.mask = np.zeros(K.getLocalSize()[0], dtype=bool)     # active entries of x
        self.its = 0
        self._KA = self._KA_mask = None
        self.op = self.ksp_amg = None
        n, N = K.getLocalSize()[0], K.getSize()[0]
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(self.prefix)
        ksp.setTolerances(rtol=1e-12, atol=1e-50, max_it=5000)
        if self.linear in SHELL_STRATEGIES:
            if self.linear in ("cg-factor", "schur"):
                apply_P = self.fac.solve
            elif self.linear in MULTIGRID_STRATEGIES:
                multigrid = self._gamg_preconditioner() if self.linear == "cg-gamg" else self._pmg_preconditioner()
                apply_P = multigrid.solve
                ksp.setInitialGuessNonzero(True)     # the previous iterate: fewer iterations
                # the true residual: GAMG's preconditioned norm is ~||K||^-1 smaller (the string:
                # 1e-12 of it left residuals of 1e-7 max|b|)
                ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
            else:
                apply_P = self._amg_preconditioner().solve
            product = K.query(PRODUCT) if self.linear in MULTIGRID_STRATEGIES else None
            op = PETSc.Mat().createPython([(n, N), (n, N)], ReducedOperator(K, self.mask, product), comm=self.comm)
            op.setUp()
            self.op = op
            ksp.setOperators(op)
            ksp.setType("cg" if self.spd else "gmres")
            if not self.spd:
                ksp.setGMRESRestart(300)
            pc = ksp.getPC()
            pc.setType("python")
            pc.setPythonContext(ReducedPC(apply_P, self.mask, K))
        elif self.linear == "lu":
            ksp.setType("preonly")
            ksp.getPC().setType("cholesky" if self.spd else "lu")
            ksp.getPC().setFactorSolverType("mumps")
        else:
            ksp.setType("cg" if self.spd else "gmres")
            ksp.getPC().setType("hypre")
            ksp.getPC().setHYPREType("boomeramg")
        ksp.setFromOptions()
        self.ksp = ksp

    def _amg_preconditioner(self):
        """One BoomerAMG set-up of K for the whole run (``cg-amg``; prefix ``<prefix>amg_``)."""
        ka = PETSc.KSP().create(self.comm)
        ka.setOptionsPrefix(self.prefix + "amg_")
        ka.setOperators(self.K)
        ka.setType("preonly")
        ka.getPC().setType("hypre")
        ka.getPC().setHYPREType("boomeramg")
        ka.setFromOptions()
        ka.setUp()
        self.ksp_amg = ka
        return ka

    def _gamg_preconditioner(self):
        """One GAMG set-up for the whole run (``cg-gamg``; prefix ``<prefix>gamg_``, defaults
        :data:`GAMG_OPTIONS`): the hierarchy from P (:data:`PMAT`, with its near-nullspace), the
        smoothing on K (:data:`PRODUCT`)."""
        ka = PETSc.KSP().create(self.comm)
        ka.setOptionsPrefix(self.prefix + "gamg_")
        ka.setOperators(self.K.query(PRODUCT) or self.K, self.K.query(PMAT) or self.K)
        ka.setType("preonly")
        ka.getPC().setType("gamg")
        with scoped_options(self.prefix + "gamg_", GAMG_OPTIONS):
            ka.setFromOptions()
            ka.setUp()
        self.ksp_amg = ka
        return ka

    def _pmg_preconditioner(self):
        """One two-level P2 -> P1 multigrid of K for the whole run (``cg-pmg``; prefix ``<prefix>pmg_``,
        defaults :data:`PMG_OPTIONS`): smoothing on K (:data:`PRODUCT`, the Jacobi diagonal from :data:`PMAT`),
        the interpolation :data:`PMG_INTERPOLATION`, GAMG on the coarse :data:`PMG_COARSE`."""
        interpolation, coarse = self.K.query(PMG_INTERPOLATION), self.K.query(PMG_COARSE)
        if interpolation is None or coarse is None:
            raise VIError("linear strategy cg-pmg needs the P2 -> P1 interpolation a run attaches to its step "
                          "matrix (sdm_dolfinx.method.iterative.attach), and this matrix has none: choose cg-gamg")
        operators = (self.K.query(PRODUCT) or self.K, self.K.query(PMAT) or self.K)    # K's cheap product, P
        ka = PETSc.KSP().create(self.comm)
        ka.setOptionsPrefix(self.prefix + "pmg_")
        ka.setOperators(*operators)
        ka.setType("preonly")
        pc = ka.getPC()
        pc.setType("mg")
        pc.setMGLevels(2)
        pc.setMGInterpolation(1, interpolation)
        pc.getMGSmoother(1).setOperators(*operators)
        pc.getMGCoarseSolve().setOperators(coarse, coarse)
        with scoped_options(self.prefix + "pmg_", PMG_OPTIONS):
            ka.setFromOptions()
            ka.setUp()
        self.ksp_amg = ka
        return ka

    def _reduced_matrix(self):
        rows = self.K.getOwnershipRange()[0] + np.flatnonzero(self.mask).astype(np.int32)
        KA = self.K.copy()
        KA.zeroRowsColumns(rows, 1.0)
        return KA

    def _linear_solve(self, rhs, x):
        shell = self.linear in SHELL_STRATEGIES
        if shell:
            self.op.assemble()
        elif self.linear == "lu" or self._KA is None or self.comm.allreduce(
                not np.array_equal(self.mask, self._KA_mask), op=MPI.LOR):
            # lu: refactorise at every iteration (the baseline); amg: set up again only when
            # the active set changed on some rank (never in the free phase)
            if self._KA is not None:
                self._KA.destroy()
            self._KA, self._KA_mask = self._reduced_matrix(), self.mask.copy()
            self.ksp.setOperators(self._KA)
        if self.linear == "lu":     # MUMPS reads its options at each factorisation
            for _, _, margin in mumps_margins(self.prefix):   # as in factorise
                with margin:
                    self.ksp.solve(rhs, x)
                if self.ksp.getConvergedReason() != PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED:
                    break
                self.ksp.getPC().reset()
                self.ksp.setOperators(self._KA)
        else:
            self.ksp.solve(rhs, x)
        reason = self.ksp.getConvergedReason()
        self.its += max(self.ksp.getIterationNumber(), 1)
        if reason <= 0:
            raise VIError(f"linear solve on the inactive set failed (KSP reason {reason}: "
                          f"{ksp_reason_name(reason)})")

    def solve(self, b, x, active, work):
        """Solve x_A = lb_A, (K x - b)_I = 0; return (x at the constraints, multipliers).

        ``work``: three vectors of K's layout (right-hand side, residual, x_A)."""
        c, lb = self.cdofs, self.lb
        rhs, res, xa = work
        self.mask[:] = False
        self.mask[c[active]] = True
        # the operator zeroes the active columns: move K_{:,A} lb_A to the right-hand side
        xa.set(0.0)
        xa.array[c[active]] = lb[active]
        self.K.mult(xa, rhs)
        rhs.aypx(-1.0, b)
        rhs.array[c[active]] = lb[active]
        x.array[c[active]] = lb[active]
        self._linear_solve(rhs, x)
        # multipliers lam = (K x - b) on the active set
        self.K.mult(x, res)
        res.axpy(-1.0, b)
        return x.array[c].copy(), res.array[c].copy()

    def destroy(self):
        self.ksp.destroy()
        if self._KA is not None:
            self._KA.destroy()
        if self.op is not None:
            self.op.destroy()
        if self.ksp_amg is not None:
            self.ksp_amg.destroy()
