"""The step of a hyperelastic run: Newton's method on a nonlinear variational inequality, each
iteration one LCP of the linear kind, solved by the semi-smooth Newton.

The step's equation is the linear scheme's with the internal force F_int(X; U^n) of
:mod:`sdm_dolfinx.method.finite_strain` in place of A X: with b the scheme's right-hand side
(L + M (alpha Vbar^n + alpha^2 U^n) for the midpoint scheme and backward Euler),

    r(X) = c_M M X + c_A F_int(X; U^n) - b,    r(X) = lam,  X_c >= lb,  lam >= 0,  lam . (X_c - lb) = 0

at the constrained dofs (r(X) = 0 elsewhere, X given at the Dirichlet dofs). Josephy-Newton: at the
iterate X_k, with the tangent T_k = dF_int/dX(X_k) and K_k = c_M M + c_A T_k, the next iterate solves the
LCP  K_k X = K_k X_k - r(X_k) + lam  (the semi-smooth Newton of :mod:`sdm_dolfinx.solvers`, warm-started
from the previous active set); it converges quadratically near the solution. ``newton="full"`` takes a
new tangent at every iteration (one factorisation each); ``"modified"`` keeps the step's first one
(one factorisation per step, linear convergence). The step ends when the residual, with the
multipliers of the active constraints taken out, is below :data:`RTOL` of the step's scale
(max |b|, max |c_A F_int|); it fails, naming the residual, after :data:`MAX_IT` iterations.
``"initial"`` keeps the linear run's step matrix c_M M + c_A A (the tangent at rest), factorised once for
the run as in a linear run: the iterations converge linearly, at the rate of K_0^-1 (T - A), fast while
the strains and rotations are moderate. Both take a new tangent, for the rest of the step, after an
iteration that reduced the error by less than half (:data:`SLOW`; the column ``tangents`` counts them).
The tangent is not a P-matrix in general, and its LCP's active-set iterations may cycle: that Newton iteration
is then made with the SPD step matrix at rest instead (as ``initial``), whose LCP has one solution (measured:
the disc at levels 3 and 4, at its impact, with full and modified). A Newton step
that more than doubles that error is halved (:data:`ACCEPT`, :data:`MAX_CUTS`; the iterates stay feasible,
a convex combination of feasible points).

The tangent is not symmetric (the energy-momentum stress mixes t_n and t_{n+1}): its LCPs are
solved with one LU factorisation (``schur``, the default) or ``lu``/``cg-factor``.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method import step_matrix as _step_matrix
from sdm_dolfinx.method.finite_strain import FiniteStrain
from sdm_dolfinx.solvers import VIError, make_vi_solver, sparse_factor_matrix

#: the convergence of a step's Newton iterations, relative to the step's scale
RTOL = 1e-10
#: Newton iterations before a step fails
MAX_IT = 30
#: iterations before a step fails with newton "modified" or "initial" (linear convergence)
MAX_IT_INITIAL = 100
#: modified and initial take a new tangent (for the rest of the step) after an iteration that reduced the error
#: by less than this factor (measured: the disc, level 2, P2/P1, modified, stalled at 8.9e-9 after 30
#: iterations at its impact step without it)
SLOW = 0.5
#: halvings of a Newton step that multiplied the error by more than ACCEPT (a non-monotone backtracking)
MAX_CUTS = 10
#: measured on the disc after its impact (P2/P1, neo-Hookean): without halving, level 1 at dt 1e-3
#: diverged; halving every step that did not decrease the error stalled level 2 at dt 5e-4 (a contact
#: vertex's unbalanced force of the step's scale moved to its neighbour and back); with 2, both pass
ACCEPT = 2.0
#: the ways to take the tangent
NEWTON = ("full", "modified", "initial")
#: the linear strategies that can solve a nonsymmetric LCP with one factorisation per tangent
STRATEGIES = ("schur", "lu", "cg-factor")


class FiniteStrainStep:
    """The step solver of a hyperelastic run of ``integ`` (its scheme, K's coefficients, the Dirichlet
    dofs), with the material ``material`` and ``newton`` (:data:`NEWTON`)."""

    def __init__(self, integ, material, newton, linear, options):
        d, ts = integ.discretisation, integ.time_scheme
        self.integ, self.discretisation, self.newton = integ, d, newton
        self.linear, self.options = ("schur" if linear == "auto" else linear), options
        self.forms = FiniteStrain(d, material, ts.finite_strain)
        self.c_M, self.c_A = integ.coefficients
        self.lb = ts.solver_bounds(integ)
        self.Un, self.F, self.r, self.MX = (d.A.createVecRight() for _ in range(4))
        self.free = np.ones(self.Un.getLocalSize(), dtype=bool)
        self.free[d.ddofs] = False
        self.lcp = self.aug = self.lcp0 = self.K = None
        self.active = np.zeros(len(d.cdofs), dtype=bool)
        self.lam = np.zeros(len(d.cdofs))
        self._linear_its, self.prefix = 0, "sdm_fs_"
        #: the last linear solve's reaction and the previous one (the variants with gap rows or friction)
        self.react = self.react_old = None

    @property
    def total_linear_its(self):
        """Linear iterations of the LCP solvers since the start of the run."""
        return self._linear_its + sum(s.total_linear_its for s in (self.lcp, self.lcp0) if s is not None)

    def begin(self, U):
        """The step starts from U^n = ``U``."""
        U.copy(self.Un)

    def residual(self, X, out):
        """out <- c_M M X + c_A F_int(X; U^n) (the step's K X of a linear run; the Dirichlet parts'
        reactions are out - b there)."""
        self.integ.mass_mult(X, self.MX)
        self.forms.force(X, self.Un, self.F)
        out.array[:] = self.c_M * self.MX.array_r + self.c_A * self.F.array_r
        return out

    def _initial(self):
        """``newton="initial"``: the LCP solver of the linear run's step matrix c_M M + c_A A (T at rest),
        factorised once for the run (collective; its K is the Integrator's)."""
        integ, d = self.integ, self.discretisation
        if self.lcp0 is None:
            self.lcp0 = self._make(integ.K, True, integ.factor_matrix, self.prefix + "0_")
        return self.lcp0, integ.K

    def _tangent(self, X):
        """A new LCP solver with K = c_M M + c_A T(X), the Dirichlet rows eliminated (collective)."""
        d = self.discretisation
        T = self.forms.tangent(X, self.Un)
        T.scale(self.c_A)
        K = T.copy()
        K.axpy(self.c_M, d.M, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        _step_matrix.identity_rows(K, d.ddofs)
        if self.lcp is not None:
            self._linear_its += self.lcp.total_linear_its
            self.lcp.destroy()
            self.K.destroy()
            if self.aug is not None:
                self.aug.destroy()
        self.aug = self._augmented(K, T) if self.linear != "lu" else None
        T.destroy()
        self.lcp = self._make(K, False, self.aug, self.prefix)
        self.K = K
        return self.lcp, K

    def _make(self, K, spd, factor_matrix, prefix):
        """The solver of the LCPs with the step matrix K (``spd``: K at rest, else a tangent)."""
        return make_vi_solver("ssn", K, self.discretisation.cdofs, self.lb, symmetric_positive=spd,
                              linear=self.linear, options=self.options, factor_matrix=factor_matrix, prefix=prefix)

    def _solve_linear(self, lcp, rhs, X):
        """One Newton iteration's LCP  K X = rhs + lam  from the last active set; returns its iterations."""
        lcp.active = self.active.copy()
        its = lcp.solve(rhs, X)["its"]
        self.active = lcp.active.copy()
        return its

    def _reaction(self, lcp, rhs, X):
        """The last iteration's reaction K X - rhs (= G^T lam, its multipliers on the owned dofs) into
        ``self.react``: the residual r(X) - b's next value to first order (collective). The variants whose error
        is measured against it (gap rows, friction) call it after every linear solve."""
        if self.react is None:
            self.react, self.react_old = self.Un.duplicate(), self.Un.duplicate()
            self.react_old.set(0.0)
        lcp.K.mult(X, self.react)
        self.react.axpy(-1.0, rhs)

    def _keep_reaction(self):
        """Before a Newton iteration: the reaction that goes with its starting iterate X_old."""
        if self.react is not None:
            self.react.copy(self.react_old)

    def _halve_reaction(self):
        """A halved Newton step (X + X_old) / 2: its reaction estimate is the mean of the two iterates'
        (the linearisation is affine between them), so that its error is comparable with theirs."""
        if self.react is not None:
            self.react.axpy(1.0, self.react_old)
            self.react.scale(0.5)

    def _reaction_error(self, res, scale):
        """max |r(X) - b - (the reaction estimate of X)| off the Dirichlet dofs over ``scale`` (0 reaction before
        the first iteration; collective)."""
        react = self.react
        e = np.abs(np.where(self.free, res - (react.array_r if react is not None else 0.0), 0.0))
        return self.discretisation.comm.allreduce(float(np.max(e, initial=0.0)), op=MPI.MAX) / scale

    def _augmented(self, K, T):
        """The sparser [c_A T, sqrt(c_M) B^T; sqrt(c_M) B, -D] to factorise instead of K (P2/P1: M is dense;
        in 3-D always, where it took the ball's level-1 tangent from 1.4 s to 0.37 s; in 2-D from AUG_MIN_ROWS rows),
        or None."""
        d = self.discretisation
        if d.B is None or d.c_lumped is None:
            return None
        return sparse_factor_matrix(K, T, d.B, d.c_lumped, np.sqrt(self.c_M), d.ddofs, symmetric=False,
                                    min_rows=0 if d.problem.mesh.topology.dim == 3 else None)

    def solve(self, b, X):
        """Solve the step for the scheme's lifted right-hand side ``b`` (its linear lifting undone here);
        X holds the initial guess and the result. Returns the info of the step (``its``: the semi-smooth
        Newton's iterations in all, ``nonlinear_its``, ``tangents``, ``n_active``)."""
        d, comm, integ = self.discretisation, self.discretisation.comm, self.integ
        free = self.free
        braw = b.copy()
        braw.array[free] += integ.lift.array_r[free]        # b before the linear lifting b - K g
        X.array[~free] = b.array_r[~free]                   # the Dirichlet values of the iterate
        bscale = comm.allreduce(float(np.max(np.abs(braw.array_r[free]), initial=0.0)), op=MPI.MAX)
        its = tangents = cuts = fallbacks = 0
        rhs, X_old = b.duplicate(), X.copy()
        err = None
        if self.react is not None:          # no reaction before the step's first iteration
            self.react.set(0.0)
        for k in range(1, (MAX_IT if self.newton == "full" else MAX_IT_INITIAL) + 1):
            res, scale = self._residual(X, braw, bscale)
            new = self._error(res, scale)
            for _ in range(MAX_CUTS if err is not None else 0):     # backtracking: the error must fall
                if new < ACCEPT * err or new <= RTOL:
                    break
                X.axpy(1.0, X_old)                  # X <- (X + X_old) / 2: feasible, the data kept
                X.scale(0.5)
                self._halve_reaction()
                cuts += 1
                res, scale = self._residual(X, braw, bscale)
                new = self._error(res, scale)
            err = new
            if k > 1 and err <= RTOL:
                break
            if self.newton == "full" or (k == 1 and self.newton == "modified") or (k > 2 and err > SLOW * before):
                lcp, K = self._tangent(X)               # a new tangent (modified, initial: a slow iteration's)
                tangents += 1
            elif k == 1:                                # initial: the run's one factorisation
                lcp, K = self._initial()
            before = err
            self._rhs(K, X, res, rhs)
            X.copy(X_old)
            self._keep_reaction()
            try:
                its += self._solve_linear(lcp, rhs, X)
            except VIError as e:
                if lcp is self.lcp0:
                    raise VIError(f"Newton iteration {k} of the finite-strain step: {e}") from None
                # the tangent's LCP (not a P-matrix: its active-set iterations may cycle): this iteration with
                # the SPD step matrix at rest instead, whose LCP has one solution (counted in fallbacks)
                lcp, K = self._initial()
                X_old.copy(X)
                self._rhs(K, X, res, rhs)
                fallbacks += 1
                try:
                    its += self._solve_linear(lcp, rhs, X)
                except VIError as e2:
                    raise VIError(f"Newton iteration {k} of the finite-strain step: {e} (and at rest: {e2})") from None
        else:
            raise VIError(f"the finite-strain Newton did not converge in {k} iterations (residual "
                          f"{err:.3g} of the step's scale, tolerance {RTOL:g}; newton {self.newton}): a smaller "
                          f"time step" + (", or newton full" if self.newton != "full" else ""))
        rhs.destroy()
        X_old.destroy()
        braw.destroy()
        return {"its": its, **self._converged(res), "nonlinear_its": k - 1, "tangents": tangents, "cuts": cuts,
                "fallbacks": fallbacks}

    def _converged(self, res):
        """The multipliers of the converged step (the residual r(X) - b ``res`` at the active constraints)
        and its counts for the step's info."""
        c = self.discretisation.cdofs
        self.lam = np.where(self.active, res[c], 0.0)
        return {"n_active": self.discretisation.comm.allreduce(int(np.count_nonzero(self.active)), op=MPI.SUM)}

    def _rhs(self, K, X, res, rhs):
        """rhs <- K X - r(X) off the Dirichlet dofs, X there: the LCP K X' = rhs + lam of the Newton
        iteration at X (``res`` = r(X))."""
        K.mult(X, rhs)
        rhs.array[self.free] -= res[self.free]
        rhs.array[~self.free] = X.array_r[~self.free]

    def _residual(self, X, braw, bscale):
        """(r(X) - b at every owned dof, the step's scale) (collective)."""
        self.residual(X, self.r)
        res = self.r.array_r - braw.array_r
        comm = self.discretisation.comm
        scale = max(bscale, comm.allreduce(float(np.max(np.abs(self.c_A * self.F.array_r), initial=0.0)),
                                           op=MPI.MAX), 1e-300)
        return res, scale

    def _error(self, res, scale):
        """max |residual| off the Dirichlet dofs, the active constraints' (nonnegative) multipliers
        taken out, over ``scale`` (collective)."""
        e = np.abs(np.where(self.free, res, 0.0))
        c = self.discretisation.cdofs
        e[c[self.active]] = np.abs(np.minimum(res[c[self.active]], 0.0))
        return self.discretisation.comm.allreduce(float(np.max(e, initial=0.0)), op=MPI.MAX) / scale

    def strain_energy(self, U):
        """int psi(C(U)) dx (collective)."""
        return self.forms.energy(U)

    def destroy(self):
        if self.lcp is not None:
            self.lcp.destroy()
            self.K.destroy()
        if self.lcp0 is not None:               # its K is the Integrator's
            self.lcp0.destroy()
        if self.aug is not None:
            self.aug.destroy()
        self.forms.destroy()
        for v in (self.Un, self.F, self.r, self.MX, self.react, self.react_old):
            if v is not None:
                v.destroy()
