"""Time schemes for the semi-discrete problem (5) (or (4)): midpoint (14)/(23) and backward Euler.

Both schemes reduce each step to one LCP with a constant matrix. Writing alpha = 2/dt
(midpoint) or 1/dt (backward Euler) and X for the constrained iterate (U^{n+1/2} for the
midpoint scheme, U^{n+1} for backward Euler):

  M formulation:   (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam
  block (U, V):    [A  alpha B^T] [X]   [L + alpha B^T V^n]   [lam]
                   [alpha B  -C ] [Y] = [alpha B U^n      ] + [ 0 ]

(eliminating Y = alpha C^-1 B (X - U^n) from the block system gives the first line with
M = B^T C^-1 B). For the midpoint scheme alpha^2 = 4/dt^2, the paper's matrix.

L is the vector assembled once, or, for a Problem that declares ``time``, L reassembled before
every step at the time the scheme evaluates the load (:meth:`Scheme.load_time`). Before every
step the data assembled once are checked unchanged (:class:`~sdm_dolfinx.method.frozen.FrozenData`).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.method import friction as _friction, schemes
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.solvers import VIError, choose_strategy, make_vi_solver, sparse_factor_matrix
from sdm_dolfinx.solvers.friction import FrictionalNewton

#: the registered time schemes' names (:mod:`sdm_dolfinx.method.schemes`)
SCHEMES = schemes.names()


class StepError(RuntimeError):
    """A time step failed; the message names the step, the time and the cause."""


class Integrator:
    """One scheme applied to one Discretisation with one time step.

    Args:
        discretisation: a :class:`sdm_dolfinx.disccretisation.Discretisation`.
        scheme: ``"midpoint"`` or ``"backward-euler"``.
        dt: the time step.
        vi_solver: ``"ssn"`` (semi-smooth Newton, default), ``"vinewtonrsls"``, ``"vinewtonssls"``.
        linear: linear strategy of the semi-smooth Newton (see :mod:`sdm_dolfinx.solvers`).
        options: extra PETSc options for the step solver.
        friction: a :class:`~sdm_dolfinx.method.friction.Friction` (None: frictionless); with
            friction the step solver is :class:`~sdm_dolfinx.solvers.friction.FrictionalNewton`
            (``vi_solver`` "ssn", ``linear`` "auto" or "schur": it factorises K once; others are refused).
    """

    def __init__(self, discretisation, scheme="midpoint", dt=1e-3, vi_solver="ssn", linear="auto", options=None,
                 friction=None):
        self.time_scheme = schemes.get(scheme)
        self.discretisation, self.scheme, self.dt = discretisation, scheme, float(dt)
        self.time_dependent = discretisation.problem.time is not None
        if self.time_dependent and self.time_scheme.load_theta is None:
            raise DiscretisationError(f"problem {discretisation.problem.name!r} has a time-dependent load, and scheme "
                                      f"{scheme!r} does not say when it evaluates it (Scheme.load_theta)")
        self.alpha = self.time_scheme.factor / self.dt
        self.block = discretisation.mass == "consistent"
        self.nW = discretisation.A.getLocalSize()[0]
        self._build()
        self.friction = friction if friction is not None and friction.on else None
        refused = _friction.check_solver(self.friction and self.friction.law, vi_solver, linear)
        if refused:
            raise DiscretisationError(refused[0])
        if linear == "auto":
            linear = choose_strategy(discretisation.num_constraints, not self.block)
        # a factorisation of K = alpha^2 B^T D^-1 B + A is cheaper through the sparser
        # augmented matrix [A, alpha B^T; alpha B, -D] when M is much denser than A (P2/P1)
        factorised = self.friction is not None or (vi_solver == "ssn" and linear in ("schur", "cg-factor"))
        self.factor_matrix = None
        if factorised and not self.block and discretisation.B is not None and discretisation.c_lumped is not None:
            d = discretisation
            self.factor_matrix = sparse_factor_matrix(self.K, d.A, d.B, d.c_lumped, self.alpha, d.ddofs)
        self.slip = None
        if self.friction is None:
            self.solver = make_vi_solver(vi_solver, self.K, discretisation.cdofs, discretisation.lb,
                                         symmetric_positive=not self.block, linear=linear, options=options,
                                         factor_matrix=self.factor_matrix)
        else:
            self._friction_solver(options)
        self.vi_solver = vi_solver

    def _friction_solver(self, options):
        d, f = self.discretisation, self.friction
        try:
            self.tdofs, thresholds = _friction.contact_dofs(d, f)
        except ValueError as e:
            raise DiscretisationError(str(e)) from None
        self.solver = FrictionalNewton(self.K, d.cdofs, self.tdofs, d.lb, law=f.law, mu=f.mu, threshold=thresholds,
                                       symmetric_positive=not self.block, options=options,
                                       factor_matrix=self.factor_matrix)
        self.slip = np.zeros(len(self.tdofs))

    def _build(self):
        d, a = self.discretisation, self.alpha
        if not self.block:
            K = d.M.copy()
            K.scale(a * a)
            K.axpy(1.0, d.A, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        else:
            p, W, H = d.problem, d.W, d.H
            u, w = ufl.TrialFunction(W), ufl.TestFunction(W)
            v, q = ufl.TrialFunction(H), ufl.TestFunction(H)
            rho = fem.Constant(p.mesh, PETSc.ScalarType(p.rho))
            al = fem.Constant(p.mesh, PETSc.ScalarType(a))
            forms = [[d.form(p.a(u, w)), d.form(al * rho * ufl.inner(v, w) * ufl.dx)],       # the degree of A, B, C
                     [d.form(al * rho * ufl.inner(u, q) * ufl.dx), d.form(-rho * ufl.inner(v, q) * ufl.dx)]]
            K = compat.assemble_matrix_block(forms)
        self.K_full = K
        # Dirichlet dofs (constant values g): identity rows and columns, lifting z = K g
        self.gsys = K.createVecRight()
        self.gsys.array[d.ddofs] = d.g.x.array[d.ddofs]
        self.lift = K.createVecLeft()
        K.mult(self.gsys, self.lift)
        self.K = K.copy()
        rows = K.getOwnershipRange()[0] + d.ddofs
        self.K.zeroRowsColumns(rows.astype(np.int32), 1.0)
        self.b = self.K.createVecLeft()
        self.X = self.K.createVecRight()
        self._tmpW = d.A.createVecLeft()
        self._tmpW2 = d.A.createVecLeft()
        self._rigid = {}
        self._mass = None if self.block else d.mass_product()     # the block variant never forms M
        # a time-dependent load: the step's L, and L at the time of a recorded state (energies)
        self._L_step = d.L.copy() if self.time_dependent else None
        self._L_state, self._L_state_t = (d.L.copy(), 0.0) if self.time_dependent else (None, None)

    def load(self, t=None):
        """The load vector L at time ``t`` (the vector assembled once when L does not depend on
        time, or when ``t`` is None)."""
        if not self.time_dependent or t is None:
            return self.discretisation.L
        if t != self._L_state_t:
            self.discretisation.load(t, self._L_state)
            self._L_state_t = t
        return self._L_state

    def rhs(self, U, V, L=None):
        """Right-hand side for the state (U^n, V^n) and the load vector ``L`` (default: the one
        assembled once), with Dirichlet lifting applied."""
        d, a, b, nW = self.discretisation, self.alpha, self.b, self.nW
        L = d.L if L is None else L
        t = self._tmpW
        if not self.block:
            V.copy(t)
            t.scale(a)
            t.axpy(a * a, U)
            self._mass(t, self._tmpW2)
            self._tmpW2.axpy(1.0, L)
            b.array[:] = self._tmpW2.array
        else:
            d.B.multTranspose(V, t)
            t.scale(a)
            t.axpy(1.0, L)
            b.array[:nW] = t.array
            bu = d.B.createVecLeft()
            d.B.mult(U, bu)
            b.array[nW:] = a * bu.array
        b.axpy(-1.0, self.lift)
        b.array[d.ddofs] = self.gsys.array[d.ddofs]
        return b

    def step(self, U, V, n, t):
        """Advance (U, V) from t to t + dt in place; returns the solver info.

        Raises:
            StepError: naming the step, the time and the cause.
        """
        d, nW = self.discretisation, self.nW
        changed = d.frozen.changed()
        if changed:
            raise StepError(f"step {n + 1} (t = {t + self.dt:.6g}): {changed}")
        L = d.load(self.time_scheme.load_time(t, self.dt), self._L_step) if self.time_dependent else None
        b = self.rhs(U, V, L)
        X = self.X
        X.array[:nW] = U.array          # initial guess: the previous displacement
        if self.block:
            X.array[nW:] = V.array
        try:
            if self.friction is None:
                info = self.solver.solve(b, X)
            else:
                info = self.solver.solve(b, X, U.array[self.tdofs].copy())
        except VIError as e:
            raise StepError(f"step {n + 1} (t = {t + self.dt:.6g}): {e}") from None
        x = X.array[:nW]
        info["gap_imposed"] = self.discretisation.comm.allreduce(
            float(np.min(x[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)
        Un = U.array.copy()
        ts = self.time_scheme
        U.array[:] = ts.displacement(x, Un)
        if self.block:
            V.array[:] = ts.velocity_block(X.array[nW:], V.array)
        else:
            V.array[:] = ts.velocity(x, Un, V.array, self.alpha)
        if self.friction is not None:
            self._friction_info(info, U.array, Un)
        info["gap_end"] = self.discretisation.comm.allreduce(
            float(np.min(U.array[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)
        return info

    def _friction_info(self, info, u, un):
        """The step's tangential force, slip (U^{n+1} - U^n at the tangential dofs) and friction
        work lam_T . (U^{n+1} - U^n)_t (<= 0), reduced over the ranks, into ``info``."""
        comm = self.discretisation.comm
        self.slip = u[self.tdofs] - un[self.tdofs]
        lam_t = self.solver.lam_t
        force, work = comm.allreduce(np.array([np.sum(lam_t), np.dot(lam_t, self.slip)]), op=MPI.SUM)
        info.update(tangential_force=float(force), friction_work=float(work))

    @property
    def lam_t(self):
        """Tangential multipliers of the last step at the owned constrained vertices (friction; else 0)."""
        return self.solver.lam_t if self.friction is not None else np.zeros(len(self.discretisation.cdofs))

    def contact_status(self, active):
        """Per owned constrained vertex, given which are in contact (``active``): 0 not in contact,
        1 in contact and sticking (or without friction), 2 in contact and slipping (the last step's
        slip set)."""
        active = np.asarray(active, dtype=bool)
        slip = np.asarray(self.solver.slip, dtype=bool) if self.friction is not None else np.zeros_like(active)
        return np.where(active, np.where(slip, 2.0, 1.0), 0.0)

    def initial_velocity(self, V):
        """The velocity unknown of this formulation from Vbar0 in W^h: Vbar0 itself, or (block
        variant) V0 in H^h with C V0 = B Vbar0 (condition (6) holds by construction)."""
        if not self.block:
            return V
        bv = self.discretisation.B.createVecLeft()
        self.discretisation.B.mult(V, bv)
        return self.discretisation.solve_C(bv)

    def boundary_gap(self, U):
        """min over every dof of W^h on the constrained boundary (P2 mid-edge nodes included) of
        U_c - bound, reduced over the ranks (+inf without such dofs)."""
        d = self.discretisation
        return d.comm.allreduce(float(np.min(U.array[d.bdofs] - d.blb, initial=np.inf)), op=MPI.MIN)

    def vertex_gap(self, U):
        """min over the constrained vertices of U_c - bound, reduced over the ranks."""
        d = self.discretisation
        return d.comm.allreduce(float(np.min(U.array[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)

    def boundary_gap_where(self, U):
        """The coordinates (gdim,) of the dof where :meth:`boundary_gap` is reached (collective)."""
        d = self.discretisation
        gap = U.array[d.bdofs] - d.blb
        k = int(np.argmin(gap)) if gap.size else -1
        _, owner = d.comm.allreduce((float(gap[k]) if k >= 0 else np.inf, d.comm.rank), op=MPI.MINLOC)
        x = d.comm.bcast(d.bx[:, k] if d.comm.rank == owner else None, root=owner)
        return x[:d.problem.mesh.geometry.dim]

    @property
    def active(self):
        """Which owned constrained dofs are active (the step solver's active set)."""
        return getattr(self.solver, "active", np.zeros(len(self.discretisation.cdofs), dtype=bool))

    @active.setter
    def active(self, mask):
        self.solver.active = mask

    @property
    def linear_its(self):
        """Linear (Krylov) iterations of the step solver since the start of the run."""
        return self.solver.total_linear_its

    @property
    def lam(self):
        """Nodal multipliers of the last step at the owned constrained dofs (>= 0)."""
        return self.solver.lam

    def energies(self, U, V, time=None):
        """(kinetic, potential) of the discrete energy J^h (Theorem 2); a time-dependent load
        enters the potential at ``time``, the time of the state (see :meth:`load`)."""
        d = self.discretisation
        t = self._tmpW
        d.A.mult(U, t)
        pot = 0.5 * U.dot(t) - U.dot(self.load(time))
        if self.block:
            cv = d.C.createVecLeft()
            d.C.mult(V, cv)
            kin = 0.5 * V.dot(cv)
        else:
            self._mass(V, t)
            kin = 0.5 * V.dot(t)
        return kin, pot

    def momentum(self, V, component):
        """Discrete momentum e^T M Vbar (or (B e)^T V) along ``component``."""
        d = self.discretisation
        if component not in self._rigid:
            self._rigid[component] = d.rigid_vector(component)
        e = self._rigid[component]
        if self.block:
            be = d.B.createVecLeft()
            d.B.mult(e, be)
            return V.dot(be)
        t = self._tmpW
        self._mass(e, t)
        return V.dot(t)

    def destroy(self):
        self.solver.destroy()
        if self.factor_matrix is not None:
            self.factor_matrix.destroy()
