"""The default step solver: a primal-dual active set method, i.e. the semi-smooth Newton
method on lam = max(0, lam - r (x_c - lb)) (Alart–Curnier, the paper's own solver).

Each step of every scheme is the variational inequality (paper, after eq. (14))

    x_c >= lb,   lam = (K x - b)_c >= 0,   lam . (x_c - lb) = 0,   (K x - b)_i = 0 off c,

with K a constant symmetric matrix (SPD in the M formulation, a symmetric saddle point in
the (U, V) block formulation) whose Dirichlet rows are identity rows. The Newton systems
are K restricted to the inactive set, solved by one of :data:`LINEAR_STRATEGIES`
(:mod:`~sdm_dolfinx.solvers.schur`, :mod:`~sdm_dolfinx.solvers.active_set`). The Newton
loop runs as a PETSc SNES of type python under the solver's own options prefix, so SNES
monitors, options and converged reasons apply.
"""
from collections.abc import Mapping
from typing import Any, Optional

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.active_set import LINEAR_STRATEGIES, MULTIGRID_STRATEGIES, InactiveSetSolver, choose_strategy
from sdm_dolfinx.solvers.active_set import missing_package
from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, vi_tolerances
from sdm_dolfinx.solvers.schur import SchurComplement


#: the multigrid strategies' Krylov tolerance for a Newton iteration whose active set is new (the full
#: tolerance, 1e-12, once the active set holds): measured on the ball (bench/README.md, "inexact Newton")
INEXACT_RTOL = 1e-6


class MissingPackageError(VIError):
    """The linear strategy asked for needs an external package this PETSc does not have."""


class SemismoothNewton:
    """Primal-dual active set (semi-smooth Newton) solver for the step LCP.

    Args:
        K: the step matrix (PETSc Mat, Dirichlet rows = identity rows).
        cdofs: owned local indices of the constrained entries of x.
        lb: their lower bounds.
        symmetric_positive: K is SPD (M formulation) -> CG; otherwise GMRES.
        linear: how the linear systems on the inactive set are solved:

            * ``"schur"``: K is factorised once per run; a system with active set A is
              x = K^-1 b + Z mu, Z = K^-1 E_A (columns cached for the whole run), with mu
              from the small dense system (E_A^T Z) mu = lb_A - (K^-1 b)_A. Each step
              costs one solve with the factorisation (plus one per newly active
              constraint); the Newton iterations themselves are dense |A| x |A| work.
            * ``"cg-factor"``: K factorised once; CG (GMRES) on the inactive set
              preconditioned by that factorisation.
            * ``"lu"``: factorise the reduced matrix at every Newton iteration (baseline).
            * ``"amg"``: CG + BoomerAMG on the reduced matrix, set up at every iteration.
            * ``"cg-amg"``: CG on the inactive set preconditioned by one BoomerAMG set-up
              of K for the whole run (for sizes where a factorisation does not fit).
            * ``"cg-gamg"``: CG on the inactive set preconditioned by one PETSc GAMG set-up
              (the hierarchy from the sparse P and the rigid body modes that
              :func:`sdm_dolfinx.method.iterative.attach` composes with K; K's own otherwise):
              no factorisation, for 3-D sizes whose factor does not fit.
            * ``"cg-pmg"``: CG on the inactive set preconditioned by one two-level P2 -> P1
              multigrid of K (the interpolation and coarse operator that
              :func:`sdm_dolfinx.method.iterative.attach` composes with K; refused without them).
            * ``"auto"``: :func:`choose_strategy` (``schur`` unless there are many
              constrained dofs; the integrator also passes the dimension and size: in 3-D
              ``cg-gamg`` when a factorisation would not fit in memory, which the integrator
              makes ``cg-pmg`` where W^h is P2).
        prefix: PETSc options prefix of this instance (same on every rank); None: a new
            ``sdm_<k>_`` (:func:`~sdm_dolfinx.solvers.options.instance_prefix`). Options
            under it, then the shared ``-sdm_...`` ones, override ``options``.
        options: default PETSc options of this instance (a dict, keys without the prefix).
        factor_matrix: optional sparser augmented matrix factorised instead of K (see
            :func:`~sdm_dolfinx.solvers.augmented.augmented_matrix`).
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
    """

    def __init__(self, K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, symmetric_positive: bool = True,
                 linear: str = "auto", prefix: Optional[str] = None, options: Optional[Mapping[str, Any]] = None,
                 factor_matrix: Optional[PETSc.Mat] = None, rtol: float = 1e-10, max_it: int = 500) -> None:
        if linear not in LINEAR_STRATEGIES:
            raise ValueError(f"unknown linear strategy {linear!r}; choose one of {', '.join(LINEAR_STRATEGIES)}")
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb, dtype=PETSc.ScalarType)
        self.num_constraints = self.comm.allreduce(len(self.cdofs), op=MPI.SUM)
        if linear == "auto":
            linear = choose_strategy(self.num_constraints, symmetric_positive)
        if missing_package(linear):
            raise MissingPackageError(f"linear strategy {linear} {missing_package(linear)}")
        self.prefix, self.options = instance_prefix(self.comm, prefix), dict(options or {})
        self.spd, self.linear = symmetric_positive, linear
        self.factor_matrix = factor_matrix
        with self.options_scope() as scope:
            self.rtol, self.max_it, self.monitor = vi_tolerances(scope, rtol, max_it)
            self._setup(K)
        self.max_it = self.snes.getTolerances()[3]       # -sdm_snes_max_it may change it
        if self.max_it < 1:
            self.destroy()
            raise VIError(f"-{self.prefix}snes_max_it (or -sdm_snes_max_it): {self.max_it} is not an integer >= 1")

    def _setup(self, K):
        """The Alart–Curnier parameter, the linear solvers and the SNES (inside the scope)."""
        self.active = np.zeros(len(self.cdofs), dtype=bool)          # active constraints
        self.lam = np.zeros(len(self.cdofs))
        diag = K.getDiagonal()
        dsum = self.comm.allreduce(float(np.sum(diag.array[self.cdofs])), op=MPI.SUM)
        nc = self.num_constraints
        self.r = dsum / nc if nc else 1.0   # the Alart–Curnier parameter r (mean diagonal)
        self.fac = self.schur = None
        if self.linear in ("schur", "cg-factor"):
            self.fac = Factorisation(K, self.spd, self.prefix + "factor_", aug=self.factor_matrix)
        if self.linear == "schur":
            # -<prefix>schur_max_active N: the largest active set solved densely (default
            # SCHUR_MAX_ACTIVE; the integrator asks 1000 in 3-D, see schur.py)
            fixed = PETSc.Options().getInt(self.prefix + "schur_max_active", 0)
            if fixed < 0:
                raise VIError(f"-{self.prefix}schur_max_active (or -sdm_schur_max_active): {fixed} is not an "
                              "integer >= 1")
            self.schur = SchurComplement(K, self.cdofs, self.lb, self.fac, max_active=fixed or None)
        self.inactive = InactiveSetSolver(K, self.cdofs, self.lb, self.spd, self.linear, self.prefix, self.fac)
        # -<prefix>inexact_rtol t: with a multigrid strategy, the Krylov tolerance of an iteration whose active
        # set is new (default INEXACT_RTOL; 0: every solve to the full tolerance); see newton()
        name = self.prefix + "inexact_rtol"
        if PETSc.Options().hasName(name) and self.linear not in MULTIGRID_STRATEGIES:   # it would be ignored
            raise VIError(f"-{name} (or -sdm_inexact_rtol) sets the loose Krylov tolerance of linear strategies "
                          f"{' and '.join(MULTIGRID_STRATEGIES)}; {self.linear} solves every Newton system exactly: "
                          f"remove it")
        loose = PETSc.Options().getReal(name, INEXACT_RTOL)
        if not 0.0 <= loose < 1.0:
            raise VIError(f"-{self.prefix}inexact_rtol (or -sdm_inexact_rtol): {loose} is not in [0, 1)")
        self.tight = self.inactive.ksp.getTolerances()[0]
        self.loose = loose if self.linear in MULTIGRID_STRATEGIES and loose > self.tight else None
        self.snes = self._make_snes()

    def options_scope(self):
        """This instance's options in the database (its ``options``, the shared ``-sdm_``
        ones) for the PETSc calls that read them."""
        return scoped_options(self.prefix, self.options, inherit=True)

    @property
    def total_linear_its(self):
        """Linear iterations (solves with the factorisation, Krylov iterations) so far."""
        return self.inactive.its + (self.schur.its if self.schur is not None else 0)

    def _make_snes(self):
        """The semi-smooth Newton as a PETSc SNES of type python (this instance's prefix):
        SNES monitors (``-sdm_snes_monitor``: the Alart–Curnier residual of each iteration),
        ``-sdm_snes_converged_reason``, ``-sdm_snes_max_it``, ``-sdm_snes_view`` and the
        converged reason apply as for any SNES."""
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(self.prefix)
        snes.setType("python")
        snes.setPythonContext(_SnesContext(self))
        self._F = self.K.createVecLeft()
        snes.setFunction(_lcp_residual(self.K), self._F)
        snes.setTolerances(max_it=self.max_it)
        ksp = snes.getKSP()             # not used: the iterations solve with self.inactive / self.schur
        ksp.setType("preonly")
        ksp.getPC().setType("none")
        snes.setFromOptions()
        return snes

    def solve(self, b, x):
        """Solve the LCP for right-hand side b; x holds the initial guess and the result.

        Runs :meth:`newton` through the SNES (see :meth:`_make_snes`).

        Returns:
            dict with ``its`` (Newton iterations) and ``n_active``.

        Raises:
            VIError: no convergence, or a failed linear solve (with the reason).
        """
        self._result = self._error = None
        with self.options_scope():      # SNES and KSP read viewers and MUMPS options at solve time
            self.snes.solve(b, x)
        if self._error is not None:
            raise self._error
        return self._result

    def newton(self, b, x, snes):
        """Solve the LCP for right-hand side b; x holds the initial guess and the result
        (called by the SNES of :meth:`_make_snes`, which ``snes`` is: it gets the
        iteration number, the residual norm and the monitor calls).

        Each iteration exchanges the infeasible constraints between the active and the
        inactive set (active with lam < 0: release; inactive with x < lb: add), which is the
        primal-dual active set / semi-smooth Newton step. For matrices that are not
        M-matrices (P2 vertex–edge coupling) full exchanges may cycle; as in Júdice & Pires'
        block principal pivoting, when the number of infeasibilities has not decreased for
        3 iterations only the infeasible constraint of largest global index is exchanged
        (Murty's rule), which terminates for any P-matrix (our Schur complement on the
        constrained dofs is SPD).

        Returns:
            dict with ``its`` (Newton iterations) and ``n_active``.
        """
        c, lb = self.cdofs, self.lb
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        tol_lam = self.rtol * scale
        tol_x = tol_lam / self.r
        schur = self.schur is not None
        if schur:       # x0 = K^-1 b once per step; the iterations reuse it
            self.schur.start(b)
        work = None
        active = self.active.copy()
        murty = MurtyRule(self.K.getOwnershipRange()[0] + c, self.comm)
        for it in range(1, self.max_it + 1):
            # Newton step: x_A = lb_A, K_II x_I = b_I - K_IA lb_A
            by_schur = schur and self.schur.system(active)
            if by_schur:
                xc, lam = by_schur
            else:
                if work is None:
                    work = (b.duplicate(), b.duplicate(), b.duplicate())
                xc, lam = self._inexact(b, x, active, work, tol_lam, tol_x)
            lam, infeasible = self._infeasible(xc, lam, active, tol_lam, tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            # the Alart–Curnier residual |lam - max(0, lam - r (x - lb))|, for SNES monitors
            res = np.where(active, np.minimum(lam, 0.0), self.r * np.minimum(xc - lb, 0.0))
            fnorm = float(np.sqrt(self.comm.allreduce(float(res @ res), op=MPI.SUM)))
            snes.setIterationNumber(it)
            snes.setFunctionNorm(fnorm)
            snes.monitor(it, fnorm)
            if self.monitor:
                n_act = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                if self.comm.rank == 0:
                    print(f"  {it:3d} semi-smooth Newton: {n_act} active, {n_inf} infeasible "
                          f"(tolerance {tol_lam:.3e})", flush=True)
            if n_inf == 0:
                if by_schur:
                    self.schur.finish(b, x, active)
                n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                return {"its": it, "n_active": n_active}
            one = murty.single(n_inf, infeasible)
            active = active ^ (infeasible if one is None else one)   # Murty: exchange one constraint only
        raise VIError(f"semi-smooth Newton did not converge in {self.max_it} iterations "
                      f"({n_inf} constraints still infeasible)")

    def _infeasible(self, xc, lam, active, tol_lam, tol_x):
        """(the multipliers, zero off the active set; which constraints are infeasible: active with
        lam < -tol_lam, inactive with x < lb - tol_x)."""
        lam = np.where(active, lam, 0.0)
        return lam, np.where(active, lam < -tol_lam, xc < self.lb - tol_x)

    def _inexact(self, b, x, active, work, tol_lam, tol_x):
        """(x at the constraints, multipliers) of the Newton system of active set ``active`` on the inactive
        set: with a multigrid strategy an inexact Newton step. A new active set's system is solved to the
        loose tolerance (``-sdm_inexact_rtol``) first; only if that active set then holds (no infeasible
        constraint) is it solved on, from there, to the full tolerance, in the same Newton iteration. So
        every active set but the last costs a loose solve, and the result is the exact method's."""
        if self.loose is None:
            return self.inactive.solve(b, x, active, work)
        self.inactive.ksp.setTolerances(rtol=self.loose)
        xc, lam = self.inactive.solve(b, x, active, work)
        _, infeasible = self._infeasible(xc, lam, active, tol_lam, tol_x)
        self.inactive.ksp.setTolerances(rtol=self.tight)
        if self.comm.allreduce(bool(infeasible.any()), op=MPI.LOR):
            return xc, lam
        return self.inactive.solve(b, x, active, work)

    def destroy(self):
        self.snes.destroy()
        self.inactive.destroy()
        if self.schur is not None:
            self.schur.destroy()
        if self.fac is not None:
            self.fac.destroy()


def _lcp_residual(K):
    """SNES function callback F(x) = K x - b (b: the SNES right-hand side, applied by PETSc)."""
    def residual(snes, x, F):
        K.mult(x, F)
    return residual


class _SnesContext:
    """python-type SNES context: the semi-smooth Newton iterations of a
    :class:`SemismoothNewton`, with their converged reason."""

    def __init__(self, ssn):
        self.ssn = ssn

    def view(self, snes, viewer):
        ssn = self.ssn
        fac = "" if ssn.fac is None else (f", one {ssn.fac.package} factorisation per run"
                                          + (" (redundant: one per rank)" if ssn.fac.redundant else ""))
        viewer.printfASCII(f"    semi-smooth Newton (primal-dual active set) on {ssn.num_constraints} bounds: "
                           f"linear strategy {ssn.linear}{fac}, complementarity tolerance {ssn.rtol:g} x max|b|, "
                           f"Alart-Curnier r = {ssn.r:.6g}\n")

    def solve(self, snes, b, x):
        R = PETSc.SNES.ConvergedReason
        try:
            self.ssn._result = self.ssn.newton(b, x, snes)
            snes.setConvergedReason(R.CONVERGED_FNORM_ABS)
        except VIError as e:                 # raised again by SemismoothNewton.solve
            self.ssn._error = e
            snes.setConvergedReason(R.DIVERGED_MAX_IT if "did not converge" in str(e) else R.DIVERGED_LINEAR_SOLVE)
