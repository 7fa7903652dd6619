"""Bound-constrained LCP solvers for one time step.

Each step of every scheme is the variational inequality (paper, after eq. (14))

    x_c >= lb,   lam = (K x - b)_c >= 0,   lam . (x_c - lb) = 0,   (K x - b)_i = 0 off c,

with K a constant symmetric matrix (SPD in the M formulation, a symmetric saddle point in
the (U, V) block formulation) whose Dirichlet rows are identity rows.

* :class:`SemismoothNewton` — the default: a primal-dual active set method, i.e. the
  semi-smooth Newton method on lam = max(0, lam - r (x_c - lb)) (Alart–Curnier, the
  paper's own solver). Its linear systems are K restricted to the inactive set.
* :class:`SnesVI` — PETSc SNES ``vinewtonrsls`` (or ``vinewtonssls``) for comparison.

Both raise :class:`VIError` (with the PETSc / active-set reason) when they fail.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

LINEAR_STRATEGIES = ("cg-factor", "lu", "amg")


class VIError(RuntimeError):
    """A step's variational inequality was not solved."""


class _options:
    """Context: extra PETSc options under ``prefix`` for the setFromOptions calls inside it.

    The defaults are set on the objects themselves, so that they never leak into the global
    options database and from one solver to the next; options given on the command line
    (``-sdm_...``) are in the database and override them.
    """

    def __init__(self, prefix, options):
        self.prefix, self.options, self.added = prefix, dict(options or {}), []

    def __enter__(self):
        opts = PETSc.Options()
        for k, v in self.options.items():
            key = self.prefix + k
            if not opts.hasName(key):
                opts.setValue(key, v)
                self.added.append(key)
        return self

    def __exit__(self, *exc):
        opts = PETSc.Options()
        for key in self.added:
            opts.delValue(key)


class _ReducedOperator:
    """y = K_A x: K with the active rows and columns replaced by the identity."""

    def __init__(self, K, active_mask):
        self.K, self.mask = K, active_mask
        self.tmp = K.createVecRight()

    def mult(self, mat, x, y):
        xa = x.getArray(readonly=True)
        self.tmp.array[:] = xa
        self.tmp.array[self.mask] = 0.0
        self.K.mult(self.tmp, y)
        y.array[self.mask] = xa[self.mask]


class _ReducedPC:
    """z = K^-1 restricted to the inactive set (identity on the active set).

    Differs from (K_A)^-1 by a term of rank |active|, so Krylov converges in at most
    |active| + 1 iterations; one factorisation of K serves the whole run.
    """

    def __init__(self, ksp_factor, active_mask):
        self.ksp, self.mask = ksp_factor, active_mask
        self.tmp = ksp_factor.getOperators()[0].createVecRight()

    def apply(self, pc, r, z):
        ra = r.getArray(readonly=True)
        self.tmp.array[:] = ra
        self.tmp.array[self.mask] = 0.0
        self.ksp.solve(self.tmp, z)
        z.array[self.mask] = ra[self.mask]


class SemismoothNewton:
    """Primal-dual active set (semi-smooth Newton) solver for the step LCP.

    Args:
        K: the step matrix (PETSc Mat, Dirichlet rows = identity rows).
        cdofs: owned local indices of the constrained entries of x.
        lb: their lower bounds.
        symmetric_positive: K is SPD (M formulation) -> CG; otherwise GMRES.
        linear: ``"cg-factor"`` (one factorisation of K per run, Krylov on the inactive set),
            ``"lu"`` (factorise the reduced matrix at every Newton iteration) or ``"amg"``
            (CG + BoomerAMG on the reduced matrix, for sizes where a factorisation does
            not fit).
        prefix: PETSc options prefix (same on every rank); options under it override.
        options: default PETSc options (a dict, keys without the prefix).
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
    """

    def __init__(self, K, cdofs, lb, symmetric_positive=True, linear="cg-factor", prefix="sdm_",
                 options=None, rtol=1e-10, max_it=500):
        if linear not in LINEAR_STRATEGIES:
            raise ValueError(f"unknown linear strategy {linear!r}; choose one of {', '.join(LINEAR_STRATEGIES)}")
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb, dtype=PETSc.ScalarType)
        self.spd, self.linear, self.prefix = symmetric_positive, linear, prefix
        self.rtol, self.max_it = rtol, max_it
        self.mask = np.zeros(K.getLocalSize()[0], dtype=bool)     # active entries of x
        self.active = np.zeros(len(self.cdofs), dtype=bool)          # active constraints
        self.lam = np.zeros(len(self.cdofs))
        diag = K.getDiagonal()
        dsum = self.comm.allreduce(float(np.sum(diag.array[self.cdofs])), op=MPI.SUM)
        nc = self.comm.allreduce(len(self.cdofs), op=MPI.SUM)
        self.r = dsum / nc if nc else 1.0   # the Alart–Curnier parameter r (mean diagonal)
        self.total_linear_its = 0
        with _options(prefix, options):
            self._setup()

    def _setup(self):
        K, n = self.K, self.K.getLocalSize()[0]
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(self.prefix)
        ksp.setTolerances(rtol=1e-12, atol=1e-50, max_it=5000)
        if self.linear == "cg-factor":
            kf = PETSc.KSP().create(self.comm)
            kf.setOptionsPrefix(self.prefix + "factor_")
            kf.setOperators(K)
            kf.setType("preonly")
            kf.getPC().setType("cholesky" if self.spd else "lu")
            kf.getPC().setFactorSolverType("mumps")
            kf.setFromOptions()
            kf.setUp()
            self.ksp_factor = kf
            N = K.getSize()[0]
            op = PETSc.Mat().createPython([(n, N), (n, N)], _ReducedOperator(K, self.mask), comm=self.comm)
            op.setUp()
            self.op = op
            ksp.setOperators(op)
            ksp.setType("cg" if self.spd else "gmres")
            if not self.spd:
                ksp.setGMRESRestart(300)
            pc = ksp.getPC()
            pc.setType("python")
            pc.setPythonContext(_ReducedPC(kf, self.mask))
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

    def _reduced_matrix(self):
        rows = self.K.getOwnershipRange()[0] + np.flatnonzero(self.mask).astype(np.int32)
        KA = self.K.copy()
        KA.zeroRowsColumns(rows, 1.0)
        return KA

    def _linear_solve(self, rhs, x):
        if self.linear == "cg-factor":
            self.op.assemble()
        else:
            KA = self._reduced_matrix()
            self.ksp.setOperators(KA)
        self.ksp.solve(rhs, x)
        reason = self.ksp.getConvergedReason()
        self.total_linear_its += max(self.ksp.getIterationNumber(), 1)
        if self.linear != "cg-factor":
            KA.destroy()
        if reason <= 0:
            raise VIError(f"linear solve on the inactive set failed (KSP reason {reason})")

    def solve(self, b, x):
        """Solve the LCP for right-hand side b; x holds the initial guess and the result.

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
        rhs, res, xa = b.duplicate(), b.duplicate(), b.duplicate()
        active = self.active.copy()
        gidx = self.K.getOwnershipRange()[0] + c           # global indices, for Murty's rule
        best, patience = np.inf, 3
        for it in range(1, self.max_it + 1):
            # Newton step: x_A = lb_A, K_II x_I = b_I - K_IA lb_A
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
            # multipliers lam = (K x - b) on the active set, 0 elsewhere
            self.K.mult(x, res)
            res.axpy(-1.0, b)
            lam = np.where(active, res.array[c], 0.0)
            infeasible = np.where(active, lam < -tol_lam, x.array[c] < lb - tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            if n_inf == 0:
                n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                return {"its": it, "n_active": n_active}
            if n_inf < best:
                best, patience = n_inf, 3
            elif patience > 0:
                patience -= 1
            else:                       # Murty: exchange one constraint only
                gmax = self.comm.allreduce(int(np.max(gidx[infeasible], initial=-1)), op=MPI.MAX)
                infeasible = gidx == gmax
            active = active ^ infeasible
        raise VIError(f"semi-smooth Newton did not converge in {self.max_it} iterations "
                      f"({n_inf} constraints still infeasible)")

    def destroy(self):
        self.ksp.destroy()
        if self.linear == "cg-factor":
            self.ksp_factor.destroy()
            self.op.destroy()


class SnesVI:
    """PETSc SNES ``vinewtonrsls`` on the step LCP (bounds via ``setVariableBounds``).

    Tolerances are relative to the right-hand side: an absolute 1e-12 stalls at round-off
    (STYLE pitfall). Known to cycle on P2/P1 at the first impact; kept for comparison.
    """

    def __init__(self, K, cdofs, lb, symmetric_positive=True, snes_type="vinewtonrsls", prefix="sdm_snes_",
                 options=None, rtol=1e-10, max_it=60):
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb)
        self.rtol = rtol
        self.lam = np.zeros(len(self.cdofs))
        self.total_linear_its = 0
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(prefix)
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
        with _options(prefix, {"snes_linesearch_type": "basic", **(options or {})}):
            snes.setFromOptions()
        self.snes = snes
        self.work = K.createVecRight()

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
        self.snes.solve(None, self.work)
        reason = self.snes.getConvergedReason()
        if reason <= 0:
            raise VIError(f"SNES {self.snes.getType()} diverged (reason {reason}: "
                          f"{_snes_reason_name(reason)})")
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


def _snes_reason_name(reason):
    names = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, "unknown")


VI_SOLVERS = ("ssn", "vinewtonrsls", "vinewtonssls")


def make_vi_solver(name, K, cdofs, lb, symmetric_positive=True, linear="cg-factor", options=None):
    """Build the step solver ``name`` (one of :data:`VI_SOLVERS`)."""
    if name == "ssn":
        return SemismoothNewton(K, cdofs, lb, symmetric_positive, linear, options=options)
    if name in ("vinewtonrsls", "vinewtonssls"):
        return SnesVI(K, cdofs, lb, symmetric_positive, snes_type=name, options=options)
    raise ValueError(f"unknown VI solver {name!r}; choose one of {', '.join(VI_SOLVERS)}")
