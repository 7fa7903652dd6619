"""Nitsche's contact term of F. Chouly, P. Hild, Y. Renard, "A Nitsche finite element method for
dynamic contact: 1. Space semi-discretization and time-marching schemes" and "2. Stability of the
schemes and numerical experiments", ESAIM: M2AN 49 (2015) 481-502 and 503-528 (HAL hal-00958695,
hal-00958710); the static method is Chouly and Hild, SIAM J. Numer. Anal. 51 (2013) 1295-1307.

Our constraint is u_c >= bound on one component c (a scalar problem: u itself): the obstacle
pushes along e = +e_c. In the paper's notation, with n = -e: u_n = -u.e, the gap g = -bound,
and the normal stress sigma_n(u) = -(sigma(u) nu).e, nu the outward normal of the boundary
(the traction's component along -e: sigma_n = n.sigma(u)n where nu = n, the flat obstacle; for
a scalar problem sigma(u) is the flux q(u) and sigma_n = -q(u).nu), so that the contact
pressure is -sigma_n >= 0. With

    P_gamma(u) = sigma_n(u) - gamma (u_n - g) = sigma_n(u) + gamma (u.e - bound),
    P_theta,gamma(v) = theta sigma_n(v) - gamma v_n = theta sigma_n(v) + gamma v.e,

the semi-discrete problem (paper 1) is M u'' + A u + R_N(u) = L with the boundary residual, on
the contact boundary Gamma_C (:mod:`.boundary`),

    R_N(u)(v) = - int theta/gamma sigma_n(u) sigma_n(v) + int 1/gamma [P_gamma(u)]_- P_theta,gamma(v),

[x]_- = min(x, 0): GetFEM's demo_dynamic_contact_1D.py (version 3, by two of the authors) writes
the same term, and tests/physics/test_nitsche.py checks ours against it on the rod. A step of
every scheme is K X = b + lam(X) with lam = -R_N(X) (X the scheme's constrained iterate). The
contact pressure p = -[P_gamma(u)]_- is the method's approximation of -sigma_n; the solver's
``lam`` is its P1-weighted nodal force int p phi_i ds at the constrained vertices (phi_i the P1
hat function, the test function of the problem's lumped measure m_i), so that sum_i lam_i is the
total contact force int p ds and lam_i / m_i (``lambda_probe``) a local average of p for any
degree of W^h (-R_N at a P2 vertex dof would weight p by the P2 vertex function, whose integral
over a facet is 1/6 of the facet's measure).

Energy. With E(u, u') = 1/2 (M u', u') + 1/2 a(u, u) - L(u), the modified energy

    E_theta = E + theta / 2 int 1/gamma ([P_gamma(u)]_-^2 - sigma_n(u)^2)

satisfies, along the semi-discrete solution (test the equation with u' and write
P_theta,gamma(u') = theta d/dt P_gamma(u) + (theta - 1) gamma u'_n),

    d/dt E_theta = (1 - theta) int [P_gamma(u)]_- u'_n,

so theta = 1 conserves it: paper 1's energy conservation of the symmetric variant, and the energy
GetFEM's demo records for every theta. (The papers' text could not be read here; the formula is
derived, and the demo's energy term is its contact part.) :meth:`Nitsche.energy` returns that
contact part. In time, with the midpoint scheme (force at X = U^{n+1/2}; P_gamma is affine in u,
so P(X) is the mean of P(U^n) and P(U^{n+1})), the same computation gives, per step, exactly

    E_theta^{n+1} - E_theta^n = theta D_n + (1 - theta) int [P_gamma(X)]_- (U^{n+1} - U^n)_n,
    D_n = int 1/(2 gamma) s min(P_n^2, P_{n+1}^2)   over the points where P changes sign,

s = +1 where P goes from > 0 to < 0 (the point enters contact), -1 where it leaves: theta = 1
conserves E_theta to round-off except at the steps where the contact set changes, where the
defect D_n is O(gamma dt^2 |u'|^2) (tests/physics/test_nitsche.py checks the identity for the
three thetas, and the order of theta = 1's energy error).

gamma = gamma0 M_n / h_T, h_T the diameter of the facet's cell (its vertices' largest distance),
M_n the problem's normal stiffness modulus: sigma_n of the unit normal strain u = x_c e_c along the
constrained axis c, also against an obstacle whose normal is another (the same for an isotropic
material; an anisotropic ``stress`` against a tilted obstacle gets the axis' modulus) (lambda +
2 mu in plane strain, E for the 1-D rod, the tension of a scalar problem), computed from
``stress`` over Gamma_C, so that gamma0 is dimensionless (gamma = gamma0 E / h for the rod, as
in GetFEM's demo; with lambda + 2 mu the scaling also follows the incompressible limit, where
sigma_n grows with lambda). Defaults: theta = 1 (:data:`DEFAULT_THETA`), the symmetric variant,
the one whose semi-discrete problem conserves E_theta (the energy the comparison measures) and
whose Newton matrix is symmetric; it needs gamma0 large enough for well-posedness (A minus the
term int theta/gamma sigma_n^2 coercive: gamma0 above an inverse-inequality constant; in the
static analysis of Chouly and Hild theta = -1 is well-posed for any gamma0 > 0). gamma0 =
:data:`DEFAULT_GAMMA0`, above that constant on every pair measured (:data:`GAMMA0_NOTE`).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.contact.boundary import (cell_diameter, check_on_boundary, contact_facets, contact_measure,
                                                 facet_cell_dofs)
from sdm_dolfinx.contact.nitsche_newton import NitscheNewton
from sdm_dolfinx.method.discretisation import owned_size
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.obstacle_rows import nearest
from sdm_dolfinx.params import Param

#: the variants of Nitsche's term: symmetric (1), incomplete (0), skew-symmetric (-1)
THETAS = (1, 0, -1)
#: the default theta: the symmetric variant (energy-conserving semi-discretisation)
DEFAULT_THETA = 1
#: the default gamma0: above the well-posedness threshold of theta = 1 on every pair measured (GAMMA0_NOTE)
DEFAULT_GAMMA0 = 20.0
#: why (measured: the largest gamma0 for which A - int 1/gamma sigma_n(.)^2 ds, the static operator
#: of theta = 1 without contact, is not positive semi-definite, with our h_T and M_n)
GAMMA0_NOTE = ("theta = 1 needs gamma0 above an inverse-inequality constant (paper 1): measured 1 (P1) and 4 "
               "(P2, P1+) on the rod; on the block (10 x 5, nu = 0 / 0.3 / 0.45) 2.4 / 2.5 / 2.7 (P1), 7.8 / 8.0 / "
               "8.2 (P2), 8.0 / 9.3 / 11.7 (P1+); gamma0 = 20 clears them all by 1.7x at least. A larger gamma0 "
               "stiffens the contact (less penetration, and with a standard mass more contact-stress oscillation: "
               "rod P1/P1, dt = 2e-3, the L2-in-time error of the contact stress 0.17 / 0.36 / 0.67 at gamma0 = 5 / 20 "
               "/ 200). GetFEM's demo uses gamma0 = 5 with theta = 0 on the P1 rod, with the same gamma = "
               "gamma0 E / h: nitsche_gamma0=5, nitsche_theta=0 is its Nitsche term")
#: the largest gamma0: Nitsche's term is gamma0 times the mesh's stiffness on the contact boundary, so the
#: Newton residual of a step (relative to max|X_B|, nitsche_newton.py) stalls near gamma0 x 2.2e-16, which
#: must stay below its 1e-8 acceptance: the disc (level 1, P2/P1, dt = 1e-4) fails at its impact from gamma0
#: = 1e9 on (residual 1.2e-8; 1e20: 1e17; 1e40: NaN), passes at 1e8; 1e6 keeps two decades of margin, and a
#: larger gamma0 is only a stiffer penalty (the contact stress error grows with it: GAMMA0_NOTE)
MAX_GAMMA0 = 1e6
#: the treatment's options (``contact_options``)
OPTIONS = (Param("nitsche_theta", DEFAULT_THETA, "Nitsche's theta: 1 (symmetric), 0 or -1 (skew-symmetric)",
                 type=int, choices=THETAS, metavar="THETA", optional=True),
           Param("nitsche_gamma0", DEFAULT_GAMMA0, "Nitsche's gamma0: gamma = gamma0 / h x the normal stiffness",
                 type=float, low=0.0, low_strict=True, expect="a finite number > 0", metavar="G0", optional=True,
                 high=MAX_GAMMA0, high_note="above, a step's Newton residual stalls near gamma0 x round-off, too "
                                            "close to its 1e-8 acceptance: the disc failed from 1e9 on; a larger "
                                            "gamma0 is only a stiffer penalty"))


def _degree(V):
    """The polynomial degree of V's element (its sub-element's for a vector element)."""
    return compat.element_degree(V)


class Nitsche:
    """Nitsche's contact term for one step matrix (see the module).

    Args:
        context: the :class:`~sdm_dolfinx.contact.context.StepContext` (its K, discretisation
            and factor_matrix).
        theta: 1, 0 or -1 (None: :data:`DEFAULT_THETA`).
        gamma0: > 0 (None: :data:`DEFAULT_GAMMA0`).

    Raises:
        DiscretisationError: the problem has no ``stress``, or constrained vertices off the boundary.
    """

    name = "nitsche"

    def __init__(self, context, theta=None, gamma0=None):
        d = context.discretisation
        p = d.problem
        self.discretisation, self.problem = d, p
        self.stress = getattr(p, "stress", None)
        if self.stress is None:
            raise DiscretisationError(f"problem {p.name!r} declares no stress(u), which Nitsche's contact term needs "
                                      f"(its normal stress on the contact boundary); use contact='exact' or 'penalty'")
        facets = contact_facets(d)
        check_on_boundary(d, facets, "Nitsche's method")
        self.ds = contact_measure(d, facets, 2 * _degree(d.W))
        self.theta = float(DEFAULT_THETA if theta is None else theta)
        self.gamma0 = float(DEFAULT_GAMMA0 if gamma0 is None else gamma0)
        msh = p.mesh
        self.c = p.constraint_component or 0
        self.modulus = self._normal_modulus()
        self.h = cell_diameter(msh)
        self.gamma = fem.Constant(msh, self.gamma0 * self.modulus) / self.h
        self.u = fem.Function(d.W)
        self.obstacle = None if d.obstacle_rows is None else ObstacleField(d, self.u)
        if self.obstacle is None:
            self.bound = fem.Function(compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 2)))
            self.bound.interpolate(lambda x: np.asarray(p.lower_bound(x), dtype=float).reshape(-1))
        else:                   # against obstacles: u . n >= bound, both Functions set before every step
            self.bound = self.obstacle.bound
        self.nW = owned_size(d.W)
        self._compile()
        #: the dofs the boundary term reads and writes: (global indices on every rank, owned local ones)
        self.dofs = facet_cell_dofs(d, facets)
        self.solver = NitscheNewton(context.K, self, factor_matrix=context.factor_matrix)

    # ------------------------------------------------------------------ the terms
    def along(self, u):
        """u.e: the displacement along the obstacle's push (u_c, or u for a scalar problem; against
        obstacles u . n, n the obstacle's normal field)."""
        if self.obstacle is not None:
            return ufl.dot(u, self.obstacle.normal)
        return u[self.c] if self.problem.shape else u

    def sigma_n(self, u):
        """-(sigma(u) nu).e (see the module): the normal stress, < 0 in compression."""
        nu = ufl.FacetNormal(self.problem.mesh)
        t = ufl.dot(self.stress(u), nu)
        if self.obstacle is not None:
            return -ufl.dot(t, self.obstacle.normal)
        return -(t[self.c] if self.problem.shape else t)

    def before_step(self, U, t, t1, weight):
        """Against obstacles: the normal field and the bound of the step, linearised at U (U^n) at
        time t (:class:`ObstacleField`; fixed obstacles only)."""
        self.obstacle.update(U, t)

    def P(self, u):
        """P_gamma(u) = sigma_n(u) + gamma (u.e - bound): < 0 where the point is in contact."""
        return self.sigma_n(u) + self.gamma * (self.along(u) - self.bound)

    def residual_form(self, u, v):
        """R_N(u)(v) (see the module)."""
        th, g = fem.Constant(self.problem.mesh, self.theta), self.gamma
        Pv = th * self.sigma_n(v) + g * self.along(v)
        return (-(th / g) * self.sigma_n(u) * self.sigma_n(v) + ufl.min_value(self.P(u), 0.0) * Pv / g) * self.ds

    def energy_form(self, u):
        """theta / 2 int 1/gamma ([P_gamma(u)]_-^2 - sigma_n(u)^2): the contact part of E_theta."""
        th = fem.Constant(self.problem.mesh, self.theta)
        Pm = ufl.min_value(self.P(u), 0.0)
        return th / (2.0 * self.gamma) * (Pm * Pm - self.sigma_n(u) ** 2) * self.ds

    def _normal_modulus(self):
        """M_n: the mean over Gamma_C of sigma_nn of the unit normal strain (see the module)."""
        p, msh = self.problem, self.problem.mesh
        x = ufl.SpatialCoordinate(msh)
        if p.shape:
            u = ufl.as_vector([x[self.c] if i == self.c else 0.0 * x[0] for i in range(p.shape[0])])
            expr = self.stress(u)[self.c, self.c]
        else:
            gdim = msh.geometry.dim
            expr = sum(self.stress(x[j])[j] for j in range(gdim)) / gdim
        one = fem.Constant(msh, 1.0)
        num, den = (msh.comm.allreduce(fem.assemble_scalar(compat.form(f * self.ds)), op=MPI.SUM)
                    for f in (expr, one))
        if den <= 0.0:
            return 1.0                  # no contact boundary anywhere: gamma is never used
        if not num > 0.0:
            raise DiscretisationError(f"problem {p.name!r}: its stress gives a normal stiffness {num / den:g} <= 0 on "
                                      f"the contact boundary; Nitsche's gamma needs a positive one")
        return float(num / den)

    def _compile(self):
        """The residual, Jacobian, energy and pressure forms, and their vector and matrix."""
        d = self.discretisation
        v, du = ufl.TestFunction(d.W), ufl.TrialFunction(d.W)
        R = self.residual_form(self.u, v)
        self._R_form = d.form(R)
        self._J_form = d.form(ufl.derivative(R, self.u, du))
        self._E_form = d.form(self.energy_form(self.u))
        q = ufl.TestFunction(d.Q1)
        self._p_form = d.form(ufl.max_value(-self.P(self.u), 0.0) * q * self.ds)
        self._R = compat.assemble_vector(self._R_form)
        self._JN = compat.assemble_matrix(self._J_form)
        self._p = compat.assemble_vector(self._p_form)
        rows = self._JN.getOwnershipRange()[0] + d.ddofs
        self._ddofs_global = rows.astype(PETSc.IntType)

    # ------------------------------------------------------------------ for the solver
    def set_state(self, x):
        """u = the owned entries of the W^h vector ``x``, ghosts updated."""
        n = self.nW
        self.u.x.array[:n] = x.array_r[:n]
        self.u.x.scatter_forward()

    def residual(self):
        """R_N(u) (a W^h vector, Dirichlet rows 0) at the state."""
        compat.assemble_vector_into(self._R, self._R_form)
        self._R.array[self.discretisation.ddofs] = 0.0
        return self._R

    def jacobian(self):
        """dR_N/du at the state (a W^h matrix, Dirichlet rows and columns 0)."""
        self._JN.zeroEntries()
        compat.petsc_module().assemble_matrix(self._JN, self._J_form)
        self._JN.assemble()
        self._JN.zeroRowsColumns(self._ddofs_global, 0.0)
        return self._JN

    def pressure_forces(self):
        """int p phi_i ds at the owned constrained vertices (p = -[P_gamma(u)]_-, the state's)."""
        compat.assemble_vector_into(self._p, self._p_form)
        self._p.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with self._p.localForm() as pl:
            return np.array(pl.array_r[self.discretisation.q1_of_c])

    # ------------------------------------------------------------------ the treatment interface
    def describe(self):
        """What run.json may record: the options and the parameters they gave."""
        return {"contact": self.name, "nitsche_theta": self.theta, "nitsche_gamma0": self.gamma0,
                "normal_modulus": self.modulus}

    def _fields_at(self, U):
        """Against obstacles: the normal and bound fields at U if no step has set them yet (the state
        recorded before the first step; the obstacles are fixed)."""
        if self.obstacle is not None and not self.obstacle.ready:
            self.obstacle.update(U, 0.0)

    def nodal_forces(self, X):
        """The reported nodal contact forces (the solver's ``lam``) at the state X: int p phi_i ds
        at the owned constrained vertices."""
        self._fields_at(X)
        self.set_state(X)
        return self.pressure_forces()

    def energy(self, U):
        """The contact part of E_theta at the state U (collective)."""
        self._fields_at(U)
        self.set_state(U)
        return float(self.problem.mesh.comm.allreduce(fem.assemble_scalar(self._E_form), op=MPI.SUM))

    def force(self, X, out):
        """``out`` = lam(X) = -R_N(X) as a W^h vector; returns ``out``."""
        self.set_state(X)
        out.array[:] = -self.residual().array_r[:len(out.array_r)]
        return out

    def destroy(self):
        self.solver.destroy()
        for o in (self._R, self._JN, self._p):
            o.destroy()


class ObstacleField:
    """Nitsche's term against rigid obstacles (fixed ones): u . n >= bound on Gamma_C with n and bound
    Lagrange Functions (W^h's degree, 1 for P1+) set before every step from the nearest obstacle at the
    current position y = x + U^n of each of their nodes: n(y) and bound = n . U^n - phi(y), the rows of
    :mod:`sdm_dolfinx.method.obstacle_rows` as fields (on a plane exactly the axis-aligned bound
    rotated; on a curved obstacle the linearisation error O(|d_t|^2 / R) of those rows)."""

    def __init__(self, d, u):
        msh, rows = d.problem.mesh, d.obstacle_rows
        family, degree = d.pair.w
        deg = 1 if family == "P+" else int(degree)
        cell, gdim = compat.cell_name(msh), rows.gdim
        self.obstacles, self.gdim, self.u = rows.obstacles, gdim, u
        self.normal = fem.Function(compat.function_space(msh, compat.element("Lagrange", cell, deg, (gdim,))))
        self.bound = fem.Function(compat.function_space(msh, compat.element("Lagrange", cell, deg)))
        self._un = fem.Function(self.normal.function_space)
        self._x = self.bound.function_space.tabulate_dof_coordinates().T.copy()       # (3, n) with ghosts
        self.owned = owned_size(d.W)
        self.ready = False                  # the fields have been set (by a step, or at the first state)

    def update(self, U, t):
        """n and bound at the state U (a PETSc vector of W^h) at time t (collective: ghosts included)."""
        self.u.x.array[:self.owned] = U.array_r[:self.owned]
        self.u.x.scatter_forward()
        self._un.interpolate(self.u)
        un = self._un.x.array.reshape(-1, self.gdim)
        y = self._x.copy()
        y[:self.gdim] += un.T
        phi, nrm, _ = nearest(self.obstacles, y, t)
        n = nrm[:self.gdim].T
        self.normal.x.array[:] = n.reshape(-1)
        self.bound.x.array[:] = np.einsum("ik,ik->i", n, un) - phi
        self.ready = True


def make(context, options):
    """The registry's factory: ``options`` may hold ``nitsche_theta`` and ``nitsche_gamma0``."""
    return Nitsche(context, options.get("nitsche_theta"), options.get("nitsche_gamma0"))
