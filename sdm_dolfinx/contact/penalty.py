"""The penalised contact: the constraint u_c >= bound replaced by springs at the constrained dofs.

The second class of D. Doyen, A. Ern, S. Piperno (SIAM J. Sci. Comput. 33 (2011) 223-249,
"enforcement with penalty") as GetFEM's ``demo_dynamic_contact_1D.py`` (version 2) writes it:
the contact force at a constrained dof i is

    lam_i(X) = k_i (lb_i - X_i)_+,      k_i = epsilon m_i,

m_i the dof's lumped measure (the one ``lambda_probe`` divides by, ``Discretisation.cmeasure``:
a length in 2-D, an area in 3-D, 1 at the point of a 1-D rod), so that lam_i / m_i =
epsilon (lb_i - X_i)_+ is a pressure and epsilon a stiffness per unit area (N/mm^3). The force
derives from the penalty energy

    E_pen(U) = sum_i k_i / 2 (lb_i - U_i)_+^2,

which joins the balance: kinetic + potential + E_pen is what an energy-conserving scheme keeps.
With the midpoint scheme (force at U^{n+1/2}) it is conserved exactly at every step where no
dof crosses its bound (E_pen is quadratic there); a dof crossing between U^n and U^{n+1}
changes it by +k_i/2 min(s_n^2, s_{n+1}^2) when it enters (s = lb_i - U_i goes from < 0 to
> 0) and by -k_i/2 min(s_n^2, s_{n+1}^2) when it leaves: s changes by O(dt) per step, so the
balance holds to O(dt^2) (tests/physics/test_penalty.py).

Choice of epsilon (the literature leaves it open; GetFEM's demo takes k = gamma0_P / h, gamma0_P =
1, for its rod of unit modulus): ``penalty`` (dimensionless, default :data:`DEFAULT_PENALTY`)
times the stiffness per unit area of the mesh at the contact,

    epsilon = penalty * sum_i A_ii / sum_i m_i      (sums over the constrained dofs; against
                                                     obstacles n_i^T A_ii n_i, the node's block),

which is E / h for the P1 rod (A_00 = E / h, m_0 = 1: GetFEM's gamma0_P = penalty) and of the
size E / h on any problem, without the problem having to declare a modulus. penalty = 1 makes
the spring as stiff as the mesh next to it: the penetration (pressure / epsilon ~ strain x h)
is of the size of the discretisation error, and the spring's frequency that of the mesh's
highest modes (an explicit scheme's CFL limit stays of the same order; GetFEM's demo estimates
dt <= 2 h / gamma0_P). Larger values reduce the penetration (measured at the constrained iterate,
where the springs act; rod, tests/physics/test_penalty.py) like 1 / penalty when the contact dofs
carry no mass (singular or redistributed mass: the force stays the contact stress), but only like
penalty^(-1/2) with a standard mass, whose contact dofs' kinetic energy m v^2 / 2 at an impact
goes into the spring (k delta^2 / 2): the impact force then grows like penalty^(1/2).

**Gap rows** (fixed rigid obstacles, ``--constrain weighted``): the same springs on the rows G x >= g,
lam_i = k_i (g_i - G_i X)_+, solved by :class:`~sdm_dolfinx.solvers.gap_newton.GapNewton` with the
compliances 1/k on its Schur complement's diagonal; the stored energy is k_i / 2 times the squared
penetration (against an obstacle the true signed distance, not the step's linearised row).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.params import Param
from sdm_dolfinx.solvers import PenaltyNewton
from sdm_dolfinx.method.gap_solver import gap_solver

#: the default ``penalty``: epsilon = 1 x the mesh's stiffness per unit area at the contact (see the module)
DEFAULT_PENALTY = 1.0
#: the largest ``penalty``: the step's Newton system (S_AA + diag(1/k_A)) mu = ... (solvers/penalty.py) holds
#: the springs' compliance 1/k, 1/penalty of the mesh's own compliance S_AA; above 1e12 it is within 1e4
#: round-offs (eps = 2.2e-16) of S_AA, so the run is the exact contact's (measured: the disc's u_probe and
#: lambda_probe agree with it to 1e-12 from penalty 1e12 on), while contact_energy = k/2 (lb - U)^2 grows like
#: penalty times the midpoint scheme's O(dt) dip of U^{n+1} (the disc, level 1: 1e12 at penalty 1e12, and
#: ~1e149 at 1e150): no penalty run above it says anything contact exact does not
MAX_PENALTY = 1e12
#: the treatment's option (``contact_options``)
OPTIONS = (Param("penalty", DEFAULT_PENALTY, "penalty parameter: epsilon = penalty x the mesh's stiffness per unit "
                 "area at the contact, see docs/methods.md", type=float, low=0.0, low_strict=True,
                 expect="a finite number > 0", metavar="EPS", optional=True, high=MAX_PENALTY,
                 high_note="above, the springs' compliance 1/penalty is lost in the round-off of the step's: that is "
                           "contact exact, with a contact energy of round-off times the penalty"),)


def stiffness_scale(discretisation):
    """sum_i A_ii / sum_i m_i over the constrained dofs (collective): the stiffness per unit
    area of the mesh at the contact (E / h for the P1 rod); 1.0 without constrained dofs."""
    d = discretisation
    diag = d.A.getDiagonal()
    stiff = float(np.sum(diag.array_r[d.cdofs]))
    if d.obstacle_rows is not None:     # obstacles: n_i^T A_ii n_i, the node block along the normal (invariant)
        stiff = _normal_stiffness(d)
    sums = d.comm.allreduce(np.array([stiff, float(np.sum(d.cmeasure))]), op=MPI.SUM)
    diag.destroy()
    if d.num_constraints == 0:
        return 1.0
    if not sums[1] > 0.0 or not sums[0] > 0.0:
        raise DiscretisationError(f"problem {d.problem.name!r}: the penalty needs constrained dofs with a positive "
                                  f"lumped measure and stiffness (sums {sums[1]:g}, {sums[0]:g})")
    return float(sums[0] / sums[1])


def _normal_stiffness(d):
    """sum over this rank's constrained nodes of n_i^T A_ii n_i (A_ii the node's gdim x gdim diagonal
    block, n_i the nearest obstacle's normal at the reference node, t = 0): the axis-aligned bound's
    A_cc for n = e_c, and unchanged when the body and the obstacle are rotated together."""
    rows = d.obstacle_rows
    _, normals = rows.reference()
    r0, total = d.A.getOwnershipRange()[0], 0.0
    for dofs, n in zip(rows.dofs, normals):
        g = (r0 + dofs).astype(PETSc.IntType)
        total += float(n @ d.A.getValues(g, g) @ n)
    return total


class Penalty:
    """The penalised contact for one step matrix (see the module).

    Args:
        context: the :class:`~sdm_dolfinx.contact.context.StepContext` (its K, discretisation,
            factor_matrix, block).
        penalty: the dimensionless factor of epsilon (None: :data:`DEFAULT_PENALTY`).

    Attributes:
        epsilon: the penalty parameter (force per unit area and unit of penetration).
        k: the owned constrained dofs' spring stiffnesses epsilon m_i.
        solver: :class:`~sdm_dolfinx.solvers.penalty.PenaltyNewton` (one factorisation of K per run).
    """

    name = "penalty"

    def __init__(self, context, penalty=None):
        d = context.discretisation
        self.discretisation = d
        self.penalty = DEFAULT_PENALTY if penalty is None else float(penalty)
        self.epsilon = self.penalty * stiffness_scale(d)
        self.k = self.epsilon * np.asarray(d.cmeasure, dtype=float)
        self.cdofs, self.lb = d.cdofs, np.asarray(d.lb, dtype=float)
        self.rows = d.obstacle_rows if d.obstacle_rows is not None else getattr(d, "weighted_rows", None)
        if self.rows is not None:       # gap rows: springs on G x >= g (obstacles, the weighted gap)
            self.solver = gap_solver(d, context.K, symmetric_positive=not context.block,
                                     factor_matrix=context.factor_matrix, stiffness=self.k)[0]
            return
        self.solver = PenaltyNewton(context.K, d.cdofs, d.lb, self.k, symmetric_positive=not context.block,
                                    factor_matrix=context.factor_matrix)

    def describe(self):
        """What run.json may record: the option and the parameter it gave."""
        return {"contact": self.name, "penalty": self.penalty, "epsilon": self.epsilon}

    def forces(self, x):
        """k (lb - x_c)_+ at the owned constrained dofs for the owned array ``x`` (gap rows: k (g - G x)_+
        with the last step's rows)."""
        if self.rows is not None:
            return self.k * np.maximum(self.solver.g - self.solver.row_values(x), 0.0)
        return self.k * np.maximum(self.lb - x[self.cdofs], 0.0)

    def nodal_forces(self, X):
        """The reported nodal contact forces (the solver's ``lam``) at the state X."""
        return self.forces(X.array_r)

    def energy(self, U, time=0.0):
        """sum_i k_i / 2 (lb_i - U_i)_+^2 over every rank (collective); gap rows: their penetration,
        against obstacles the true signed distance -phi(a_i + U_i, t) at the state's ``time`` (a moving
        obstacle: E + this - obstacle_work is conserved by the midpoint scheme in sustained contact on a
        plane, the springs' force k s at X being their energy's exact difference quotient there), for the
        weighted gap g_i - G_i U."""
        if self.rows is None:
            s = np.maximum(self.lb - U.array_r[self.cdofs], 0.0)
        elif self.rows is self.discretisation.obstacle_rows:
            s = np.maximum(-self.rows.phi(U.array_r, 0.0 if time is None else time), 0.0)
        else:
            s = np.maximum(self.rows.g - self.solver.row_values(U.array_r), 0.0)
        return float(self.discretisation.comm.allreduce(float(0.5 * np.sum(self.k * s * s)), op=MPI.SUM))

    def force(self, X, out):
        """``out`` = lam(X): the spring forces at the constrained dofs, 0 elsewhere; returns ``out`` (the
        axis-aligned bound's: the schemes that ask for it, Newmark and the explicit ones, refuse gap rows)."""
        if self.rows is not None:
            raise NotImplementedError("the penalty's force vector on gap rows (G^T lam): no scheme that takes "
                                      "gap rows asks for it")
        out.set(0.0)
        out.array[self.cdofs] = self.forces(X.array_r)
        return out

    def destroy(self):
        self.solver.destroy()


def make(context, options):
    """The registry's factory: ``options`` may hold ``penalty``."""
    return Penalty(context, options.get("penalty"))
