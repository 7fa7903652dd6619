"""Time schemes for the semi-discrete problem (5) (or (4)): midpoint (14)/(23) and backward Euler.

Both schemes reduce each step to one LCP with a constant matrix. Writing alpha = 2/dt
(midpoint) or 1/dt (backward Euler) and X for the constrained iterate (U^{n+1/2} for the
midpoint scheme, U^{n+1} for backward Euler):

  M formulation:   (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam
  block (U, V):    [A  alpha B^T] [X]   [L + alpha B^T V^n]   [lam]
                   [alpha B  -C ] [Y] = [alpha B U^n      ] + [ 0 ]

(eliminating Y = alpha C^-1 B (X - U^n) from the block system gives the first line with
M = B^T C^-1 B). For the midpoint scheme alpha^2 = 4/dt^2, the paper's matrix.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from . import compat
from .vi import VIError, make_vi_solver

SCHEMES = {"midpoint": 2.0, "backward-euler": 1.0}
#: where each scheme imposes the constraint (and so where it holds exactly)
CONSTRAINED_ITERATE = {"midpoint": "U^{n+1/2}", "backward-euler": "U^{n+1}"}


class StepError(RuntimeError):
    """A time step failed; the message names the step, the time and the cause."""


class Integrator:
    """One scheme applied to one Discretisation with one time step.

    Args:
        disc: a :class:`sdm_dolfinx.discretisation.Discretisation`.
        scheme: ``"midpoint"`` or ``"backward-euler"``.
        dt: the time step.
        vi_solver: ``"ssn"`` (semi-smooth Newton, default), ``"vinewtonrsls"``, ``"vinewtonssls"``.
        linear: linear strategy of the semi-smooth Newton (see :mod:`sdm_dolfinx.vi`).
        options: extra PETSc options for the step solver.
    """

    def __init__(self, disc, scheme="midpoint", dt=1e-3, vi_solver="ssn", linear="cg-factor", options=None):
        if scheme not in SCHEMES:
            raise ValueError(f"unknown scheme {scheme!r}; choose one of {', '.join(SCHEMES)}")
        self.disc, self.scheme, self.dt = disc, scheme, float(dt)
        self.alpha = SCHEMES[scheme] / self.dt
        self.block = disc.mass == "consistent"
        self.nW = disc.A.getLocalSize()[0]
        self._build()
        self.solver = make_vi_solver(vi_solver, self.K, disc.cdofs, disc.lb,
                                     symmetric_positive=not self.block, linear=linear, options=options)
        self.vi_solver = vi_solver

    def _build(self):
        d, a = self.disc, self.alpha
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
            forms = [[compat.form(p.a(u, w)), compat.form(al * rho * ufl.inner(v, w) * ufl.dx)],
                     [compat.form(al * rho * ufl.inner(u, q) * ufl.dx), compat.form(-rho * ufl.inner(v, q) * ufl.dx)]]
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

    def rhs(self, U, V):
        """Right-hand side for the state (U^n, V^n), with Dirichlet lifting applied."""
        d, a, b, nW = self.disc, self.alpha, self.b, self.nW
        t = self._tmpW
        if not self.block:
            V.copy(t)
            t.scale(a)
            t.axpy(a * a, U)
            d.M.mult(t, self._tmpW2)
            self._tmpW2.axpy(1.0, d.L)
            b.array[:] = self._tmpW2.array
        else:
            d.B.multTranspose(V, t)
            t.scale(a)
            t.axpy(1.0, d.L)
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
        d, nW = self.disc, self.nW
        b = self.rhs(U, V)
        X = self.X
        X.array[:nW] = U.array          # initial guess: the previous displacement
        if self.block:
            X.array[nW:] = V.array
        try:
            info = self.solver.solve(b, X)
        except VIError as e:
            raise StepError(f"step {n + 1} (t = {t + self.dt:.6g}): {e}") from None
        x = X.array[:nW]
        info["gap_imposed"] = self.disc.comm.allreduce(
            float(np.min(x[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)
        Un = U.array.copy()
        if self.scheme == "midpoint":
            U.array[:] = 2.0 * x - Un
            if self.block:
                V.array[:] = 2.0 * X.array[nW:] - V.array
            else:
                V.array[:] = 2.0 * self.alpha * (x - Un) - V.array
        else:
            U.array[:] = x
            if self.block:
                V.array[:] = X.array[nW:]
            else:
                V.array[:] = self.alpha * (x - Un)
        info["gap_end"] = self.disc.comm.allreduce(
            float(np.min(U.array[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)
        return info

    @property
    def lam(self):
        """Nodal multipliers of the last step at the owned constrained dofs (>= 0)."""
        return self.solver.lam

    def energies(self, U, V):
        """(kinetic, potential) of the discrete energy J^h (Theorem 2)."""
        d = self.disc
        t = self._tmpW
        d.A.mult(U, t)
        pot = 0.5 * U.dot(t) - U.dot(d.L)
        if self.block:
            cv = d.C.createVecLeft()
            d.C.mult(V, cv)
            kin = 0.5 * V.dot(cv)
        else:
            d.M.mult(V, t)
            kin = 0.5 * V.dot(t)
        return kin, pot

    def momentum(self, V, component):
        """Discrete momentum e^T M Vbar (or (B e)^T V) along ``component``."""
        d = self.disc
        if component not in self._rigid:
            self._rigid[component] = d.rigid_vector(component)
        e = self._rigid[component]
        if self.block:
            be = d.B.createVecLeft()
            d.B.mult(e, be)
            return V.dot(be)
        t = self._tmpW
        d.M.mult(e, t)
        return V.dot(t)

    def destroy(self):
        self.solver.destroy()
