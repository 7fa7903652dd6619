"""One time step of a scheme on a Discretisation: the step's LCP  K X = b + lam  and the update.

For the paper's schemes (midpoint (14)/(23), backward Euler), writing alpha = 2/dt (midpoint) or
1/dt (backward Euler) and X for the constrained iterate (U^{n+1/2} for the midpoint scheme,
U^{n+1} for backward Euler):

  M formulation:   (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam
  block (U, V):    [A  alpha B^T] [X]   [L + alpha B^T V^n]   [lam]
                   [alpha B  -C ] [Y] = [alpha B U^n      ] + [ 0 ]

(eliminating Y = alpha C^-1 B (X - U^n) from the block system gives the first line with
M = B^T C^-1 B). For the midpoint scheme alpha^2 = 4/dt^2, the paper's matrix. Every scheme
(:mod:`sdm_dolfinx.schemes`) chooses its constant step matrix K = c_M M + c_A A (or its own,
:mod:`.step_matrix`), builds its right-hand side, may keep state between steps (Newmark's
acceleration: :attr:`Integrator.stateful`) and updates (U, V) from X; an explicit scheme solves
with M only (:mod:`.step_mass`). A contact treatment other than the exact one (penalty, Nitsche:
:mod:`sdm_dolfinx.contact`) replaces the VI by its own step solver.

L is the vector assembled once, or, for a Problem that declares ``time``, L reassembled before
every step at the time the scheme evaluates the load (:meth:`Scheme.load_time`). Before every
step the data assembled once are checked unchanged (:class:`~sdm_dolfinx.method.frozen.FrozenData`).
A Problem's Dirichlet parts (prescribed displacements that may move) are lifted at every step and
their reactions reported by :mod:`.prescribed`.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import iterative as _iterative, matrix_free as _matrix_free, moving_bound as _mb
from sdm_dolfinx.method import step_matrix as _step_matrix
from sdm_dolfinx.method import obstacle_rows as _obstacles
from sdm_dolfinx.method.gap_solver import gap_solver
from sdm_dolfinx.contact import friction as _friction, friction_bound as _friction_bound
from sdm_dolfinx.contact.context import StepContext
from sdm_dolfinx.run import prescribed as _prescribed, solver_rules
from sdm_dolfinx.run.finite_strain_step import FiniteStrainStep
from sdm_dolfinx.run.finite_strain_friction import FrictionalFiniteStrainStep
from sdm_dolfinx.run.finite_strain_rows import GapFiniteStrainStep
from sdm_dolfinx.run.measures import Measures
from sdm_dolfinx import materials, schemes
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.solvers import VIError, choose_strategy, make_vi_solver, sparse_factor_matrix
from sdm_dolfinx.solvers.schur import SCHUR_MAX_ACTIVE_3D

#: the registered time schemes' names (:mod:`sdm_dolfinx.schemes`)
SCHEMES = schemes.names()


class Integrator(Measures):
    """One scheme applied to one Discretisation with one time step.

    Args:
        discretisation: a :class:`sdm_dolfinx.disccretisation.Discretisation`.
        scheme: a registered scheme's name (:data:`SCHEMES`: ``"midpoint"``, ``"backward-euler"``,
            ``"newmark"``, ``"hht"``, ``"central-difference"``, ``"paoli-schatzman"``,
            ``"taylor-flanagan"``).
        dt: the time step.
        vi_solver: ``"ssn"`` (semi-smooth Newton, default), ``"vinewtonrsls"``, ``"vinewtonssls"``.
        linear: linear strategy of the semi-smooth Newton (see :mod:`sdm_dolfinx.solvers`).
        options: extra PETSc options for the step solver.
        friction: a :class:`~sdm_dolfinx.contact.friction.Friction` (None: frictionless); with
            friction the step solver is :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`
            (``vi_solver`` "ssn", ``linear`` "auto" or "schur": it factorises K once; others are refused).
        scheme_options: the scheme's parameters, a dict with keys among ``hht_alpha``,
            ``restitution`` (None values: the scheme's defaults; see the scheme's module).
        contact: ``"exact"`` (the VI, default) or a contact treatment of
            :mod:`sdm_dolfinx.contact` (``"penalty"``, ``"nitsche"``).
        contact_options: the treatment's parameters (``penalty``, ``nitsche_theta``, ``nitsche_gamma0``).
        material: ``"linear"`` (the Problem's a(u, w), default) or a hyperelastic material of
            :mod:`sdm_dolfinx.materials` (``"svk"``, ``"neo-hookean"``, ``"problem"``): the step is then
            Newton's method on a nonlinear VI (:mod:`.finite_strain_step`).
        newton: a hyperelastic run's tangent: ``"full"`` (every Newton iteration), ``"modified"`` (once
            per step) or ``"initial"`` (the step matrix at rest, factorised once for the run; a new tangent
            after a slow iteration).

    Raises:
        DiscretisationError: a combination the scheme or the treatment refuses (one line).
        ValueError: a scheme parameter it does not take, or out of its range.
    """

    def __init__(self, discretisation, scheme="midpoint", dt=1e-3, vi_solver="ssn", linear="auto", options=None,
                 friction=None, scheme_options=None, contact="exact", contact_options=None, material="linear",
                 newton="full"):
        self.time_scheme = ts = schemes.get(scheme).configure(scheme_options)
        self.discretisation, self.scheme, self.dt = discretisation, scheme, float(dt)
        self.contact, self.vi_solver = contact, vi_solver
        self.time_dependent = discretisation.problem.time is not None
        if self.time_dependent and ts.load_theta is None:
            raise DiscretisationError(f"problem {discretisation.problem.name!r} has a time-dependent load, and scheme "
                                      f"{scheme!r} does not say when it evaluates it (Scheme.load_theta)")
        self.alpha = ts.factor / self.dt if ts.factor is not None else None
        self.block = discretisation.mass == "consistent"
        self.nW = discretisation.A.getLocalSize()[0]
        self.friction = friction if friction is not None and friction.on else None
        self.treatment, self.state = None, None
        #: the material of a hyperelastic run (:mod:`sdm_dolfinx.materials`), or None (linear)
        self.finite_strain = None if materials.is_linear(material) else material
        self.newton = newton
        #: the Problem's Dirichlet parts (:class:`~.prescribed.Prescribed`: data lifted at every step,
        #: reactions and their work reported), or None
        self.parts = _prescribed.Prescribed() if discretisation.problem.dirichlet_parts else None
        refused = _friction.check_solver(self.friction and self.friction.law, vi_solver, linear)
        parts_refused = self.parts.refuse(self) if self.parts else None
        refused = refused or [r for r in (solver_rules.finite_strain_refusal(self, vi_solver, linear),
                                          _obstacles.refusal(self, ts, vi_solver, linear), solver_rules.contact_refusal(self),
                                          parts_refused, _iterative.refusal(discretisation, linear, self.block),
                                          _mb.refusal(discretisation, ts, contact), ts.refuse(self)) if r]
        if refused:
            raise DiscretisationError(refused[0])
        solver_rules.warn_unused_strain_energy(self)
        ts.setup(self)
        linear = self._resolve(linear)
        self._build(linear)
        self._make_solver(vi_solver, linear, options, contact_options)
        self.moving = _mb.MovingBound(discretisation, ts, self.dt, self.solver)     # a moving obstacle's bounds
        ts.prepare(self)

    @property
    def stateful(self):
        """The scheme keeps state beyond (U, V) between steps (Newmark's acceleration): a
        checkpoint of U and V cannot restart it."""
        return bool(self.time_scheme.stateful)

    def _resolve(self, linear):
        """The linear strategy ``linear`` means (``auto``: :func:`~sdm_dolfinx.solvers.choose_strategy`)."""
        d = self.discretisation
        #: the linear strategy used, and why
        self.linear_strategy, self.linear_reason = linear, "asked for"
        if linear == "auto" and self.finite_strain:      # a new nonsymmetric tangent: one LU each
            linear, self.linear_strategy, self.linear_reason = "schur", "schur", "auto: a hyperelastic run's tangent"
        if linear == "auto":
            n = d.A.getSize()[0] + (d.C.getSize()[0] if self.block else 0)
            linear, why = choose_strategy(d.num_constraints, not self.block, n, d.problem.mesh.topology.dim, d.comm,
                                          explain=True)
            linear, why = _iterative.prefer_pmg(d, linear, why, self.block)     # P2: cg-gamg -> cg-pmg
            self.linear_strategy, self.linear_reason = linear, f"auto: {why}"
        return linear

    def _make_solver(self, vi_solver, linear, options, contact_options):
        d = self.discretisation
        if linear in ("cg-gamg", "cg-pmg") and not self.block:     # GAMG's near-nullspace, P ~ K, a cheap K x
            self._gamg = _iterative.attach(self.K, d, self.coefficients, coarse=linear == "cg-pmg")
        # K = c_M B^T D^-1 B + A factorised through the sparser [A, sqrt(c_M) B^T; sqrt(c_M) B, -D] (P2/P1)
        factorised = (self.friction is not None or d.obstacle_rows is not None or d.weighted_rows is not None
                      or d.body_rows is not None or (vi_solver == "ssn" and linear in ("schur", "cg-factor")))
        self.factor_matrix = None
        if (factorised and not self.block and self.coefficients is not None and self.coefficients[1] == 1.0
                and d.B is not None and d.c_lumped is not None):
            c_M, a = self.coefficients[0], self.alpha
            scale = a if a is not None and a * a == c_M else np.sqrt(c_M)
            self.factor_matrix = sparse_factor_matrix(self.K, d.A, d.B, d.c_lumped, scale, d.ddofs)
        self.slip = None
        #: what the step's gap rows are asked for besides U^n (friction between bodies: their tangential rows)
        self.row_options: dict = {}
        gap_rows = (d.obstacle_rows is not None or d.weighted_rows is not None
                    or d.body_rows is not None) and self.friction is None
        if gap_rows and self.contact == "exact" and self.finite_strain:     # a gap-row solver per tangent
            self.solver = GapFiniteStrainStep(self, self.finite_strain, self.newton, linear, options)
        elif gap_rows and self.contact == "exact":            # G x >= g (method/gap_solver.py)
            self.solver, self.linear_strategy, self.linear_reason = gap_solver(
                d, self.K, vi_solver, not self.block, options, self.factor_matrix)
        elif self.contact != "exact":
            from sdm_dolfinx import contact as _contact  # lazily: a registry of its own
            context = StepContext(self.K, d, self.dt, self.block, self.factor_matrix)     # never the Integrator
            self.treatment = _contact.make(self.contact, context, dict(contact_options or {}))
            self.solver = self.treatment.solver
        elif self.friction is None:
            if d.problem.mesh.topology.dim == 3:     # many more active vertices: see solvers.schur
                options = {"schur_max_active": str(SCHUR_MAX_ACTIVE_3D), **(options or {})}
            if self.finite_strain:
                self.solver = FiniteStrainStep(self, self.finite_strain, self.newton, linear, options)
            else:
                self.solver = make_vi_solver(vi_solver, self.K, d.cdofs, self.time_scheme.solver_bounds(self),
                                             symmetric_positive=not self.block, linear=linear, options=options,
                                             factor_matrix=self.factor_matrix)
        elif self.finite_strain:            # a new frictional solver per tangent
            self.solver = FrictionalFiniteStrainStep(self, self.finite_strain, self.newton, linear, options,
                                                     _friction.solver_factory(self, options))
        else:
            self.solver = _friction.make_solver(self, options)
            if self.friction.law == "coulomb":          # up front: a mu the measured bound does not cover
                _friction_bound.warn_if_above(self, self.friction.mu)
        if self.finite_strain:              # the reactions of the Dirichlet parts: K X - b with its force
            self.apply_step = self.solver.residual

    def _build(self, linear):
        d, ts = self.discretisation, self.time_scheme
        K = ts.step_matrix(self)
        #: (c_M, c_A) of K = c_M M + c_A A, or None (the block variant, a scheme's own matrix)
        self.coefficients = None
        #: K is the operator of :mod:`~sdm_dolfinx.method.matrix_free` (never assembled, M never formed)
        self.matrix_free = False
        if K is None and not self.block:
            self.coefficients = ts.coefficients(self.dt)
            self.matrix_free = _matrix_free.refusal(self, linear) is None
            K = (_matrix_free.operator(d, *self.coefficients, dirichlet=False) if self.matrix_free
                 else _step_matrix.combination(d, *self.coefficients))
        elif K is None:
            K = _step_matrix.block_matrix(d, self.alpha)
        self.K_full = K
        #: y <- the step's K X (a hyperelastic run: c_M M X + c_A F_int(X; U^n)), for the reactions
        self.apply_step = K.mult
        # Dirichlet dofs (constant values g): identity rows and columns, lifting z = K g
        self.K, self.gsys, self.lift = (_matrix_free.eliminate(K, d, *self.coefficients) if self.matrix_free
                                        else _step_matrix.eliminate(K, d))
        self.b = self.K.createVecLeft()
        self.X = self.K.createVecRight()
        self._tmpW = d.A.createVecLeft()
        self._tmpW2 = d.A.createVecLeft()
        self._rigid = {}
        self._mass = (None if self.block else     # the block variant never forms M, nor does a matrix-free K
                      self.K.getPythonContext().mass if self.matrix_free else d.mass_product())
        # a time-dependent load: the step's L, and L at the time of a recorded state (energies)
        self._L_step = d.L.copy() if self.time_dependent else None
        self._L_state, self._L_state_t = (d.L.copy(), 0.0) if self.time_dependent else (None, None)
        if self.parts:
            self.parts.build(self)

    def load(self, t=None):
        """The load vector L at time ``t`` (the vector assembled once when L does not depend on
        time, or when ``t`` is None)."""
        if not self.time_dependent or t is None:
            return self.discretisation.L
        if t != self._L_state_t:
            self.discretisation.load(t, self._L_state)
            self._L_state_t = t
        return self._L_state

    def rhs(self, U, V, L=None, t=0.0):
        """Right-hand side of the step from the state (U^n, V^n) at time ``t`` with the load
        vector ``L`` (default: the one assembled once), Dirichlet lifting applied (the scheme's
        :meth:`~sdm_dolfinx.schemes.base.Scheme.rhs`)."""
        return self.time_scheme.rhs(self, U, V, self.discretisation.L if L is None else L, t)

    def alpha_rhs(self, U, V, L):
        """b = L + M (alpha V^n + alpha^2 U^n) (block: [L + alpha B^T V^n; alpha B U^n]), lifted:
        the right-hand side of the paper's schemes."""
        d, a, b, nW = self.discretisation, self.alpha, self.b, self.nW
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
        return self.lifted(b)

    def lifted(self, b):
        """b with the Dirichlet lifting: b - K g off the Dirichlet dofs, g on them (in place)."""
        d = self.discretisation
        if self.parts:              # the reactions are K X - b at the Dirichlet rows, b before the lifting
            self.parts.unlifted(self, b)
        b.axpy(-1.0, self.lift)
        b.array[d.ddofs] = self.gsys.array[d.ddofs]
        return b

    def mass_mult(self, x, y):
        """y = M x (M formulation)."""
        self._mass(x, y)

    def step(self, U, V, n, t):
        """Advance (U, V) from t to t + dt in place; returns the solver info.

        Raises:
            StepError: naming the step, the time and the cause.
        """
        d, ts = self.discretisation, self.time_scheme
        changed = d.frozen.changed()
        if changed:
            raise StepError(f"step {n + 1} (t = {t + self.dt:.6g}): {changed}")
        L = d.load(ts.load_time(t, self.dt), self._L_step) if self.time_dependent else d.L
        if self.parts:
            self.parts.lift(self, U, t)
        self.moving.before_step(n, t)       # a moving obstacle: the step's bound into d.lb (else nothing)
        rows, t1 = d.obstacle_rows or d.body_rows, ((n + 1) * self.dt if t == n * self.dt else t + self.dt)
        if rows is not None and hasattr(self.treatment, "before_step"):    # Nitsche: its fields at U^n
            self.treatment.before_step(U, t, t1, ts.bound_weight)
        elif rows is not None:              # gap rows linearised at U^n (method/obstacle_rows.py)
            self.solver.set_rows(*rows.rows(U.array_r, t, t1, ts.bound_weight, **self.row_options))
        if ts.stateful and self.state is None:
            self.state = ts.start(self, U, V, t)
        b = ts.rhs(self, U, V, L, t)
        if self.finite_strain:
            self.solver.begin(U)
        X = self.X
        ts.guess(self, U, V, X)         # initial guess: the previous displacement
        try:
            if self.friction is None:
                info = self.solver.solve(b, X)
            else:
                info = self.solver.solve(b, X, _friction.slip_reference(self, U.array_r))
        except VIError as e:
            raise StepError(f"step {n + 1} (t = {t + self.dt:.6g}): {e}{_friction_bound.step_hint(self)}") from None
        comm = d.comm
        # a contact treatment imposes nothing (penetration is its model): +inf
        gap_rows = rows is not None or d.weighted_rows is not None
        imposed = (float("inf") if self.treatment is not None
                   else self.solver.imposed_gap(X.array_r) if gap_rows        # the gap rows' own G X - g
                   else ts.imposed_gap(self, X))
        info["gap_imposed"] = comm.allreduce(imposed, op=MPI.MIN)
        self.moving.after_solve(self.lam, info)     # the bound at t_{n+1}, the step's obstacle_work
        Un = U.array.copy() if self.friction is not None else None
        Un_D = U.array[d.ddofs].copy() if self.parts else None
        ts.update(self, X, U, V, t)
        if self.parts:
            self.parts.reactions(self, info, X, U, Un_D)
        if self.friction is not None:
            _friction.step_info(self, info, U.array, Un)
        if rows is not None:                # the true signed distance at t_{n+1}, and the obstacles' work
            rows.after_step(info, U.array_r, t1, self.lam)
            if "obstacle_friction_work" in info:        # the friction force's on the moving obstacle too
                info["obstacle_work"] += info.pop("obstacle_friction_work")
        else:
            info["gap_end"] = comm.allreduce(float(np.min(U.array[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)
        return info

    @property
    def lam_t(self):
        """Tangential multipliers of the last step at the owned constrained vertices (friction; else 0;
        3-D: their size |lam_T|, the solver's ``lam_t`` has both components)."""
        if self.friction is None:
            return np.zeros(len(self.discretisation.cdofs))
        lam_t = self.solver.lam_t
        return lam_t if lam_t.ndim == 1 else np.linalg.norm(lam_t, axis=1)

    @property
    def lam_t_components(self):
        """Tangential multipliers of the last step at the owned constrained vertices, signed: m in
        2-D, m x 2 in 3-D (the tangential axes in increasing order; obstacles: m x 3, Cartesian;
        friction, else 0)."""
        if self.friction is None:
            return np.zeros(len(self.discretisation.cdofs))
        return np.asarray(self.solver.cartesian(self.solver.lam_t))

    @property
    def slipping(self):
        """Which owned constrained vertices slipped in the last step (the frictional step solver's
        slip set; None without friction)."""
        return None if self.friction is None else np.asarray(self.solver.slip, dtype=bool)

    def destroy(self):
        if self.treatment is not None:
            self.treatment.destroy()            # its solver included
        else:
            self.solver.destroy()
        if self.factor_matrix is not None:
            self.factor_matrix.destroy()
        self.time_scheme.destroy(self)
        if self.parts:
            self.parts.destroy()
