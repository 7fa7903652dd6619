"""A hyperelastic body on a Discretisation: the step's internal force, its tangent and the strain energy.

The mass M = B^T C^-1 B is a reference-configuration quantity and is the same as in a linear run;
the internal force int P_alg : grad w dx replaces A X (:mod:`sdm_dolfinx.materials.algorithmic`:
which stress a scheme evaluates) and int psi(C(u)) dx replaces 1/2 U^T A U in the energy. All
three forms take one quadrature degree (:func:`degree`), so the discrete gradient's identity
P_alg : grad(U^{n+1} - U^n) = psi(C_1) - psi(C_0), which holds at every quadrature point, holds
for the assembled energy too.

At set-up the tangent at rest is compared with the Problem's own A: a material whose
linearisation is not the Problem's a(u, w) (other Lame parameters, plane stress, an extra term
such as an elastic foundation, which the material would leave out) is refused in one line.
"""
from mpi4py import MPI
from petsc4py import PETSc

import ufl
from dolfinx import fem

from sdm_dolfinx import compat, materials
from sdm_dolfinx.materials import algorithmic
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.method.errors import DiscretisationError

#: the largest |T_0 - A| / |A| (Frobenius) accepted: the material's tangent at rest is the Problem's A
REST_TOL = 1e-8


def degree(d):
    """The quadrature degree of the finite-strain forms: 4 (k - 1) for W^h of degree k, exact for Saint
    Venant-Kirchhoff on affine cells (psi and P_alg : grad w are of that degree), plus 2 on curved cells
    (the disc's and the ball's P2 geometry), at least 2. Not the linear forms' 12 on curved cells: the
    energy-momentum stress and its tangent at degree 12 on tetrahedra made a C file whose compilation
    exhausted 24 GB (the ball, neo-Hookean)."""
    k = compat.element_degree(d.W)
    return max(4 * (k - 1) + (0 if quadrature.is_affine(d.problem.mesh) else 2), 2)


class FiniteStrain:
    """The forms of ``material`` (a registered name) on ``d`` for a scheme whose internal force is
    ``kind`` (:data:`sdm_dolfinx.materials.algorithmic.KINDS`).

    Raises:
        DiscretisationError: the material cannot model the Problem, or its tangent at rest is not A.
    """

    def __init__(self, d, material, kind):
        self.discretisation, self.kind = d, kind
        self.material = m = materials.get(material)
        p = d.problem
        refused = m.refusal(p)
        if refused:
            raise DiscretisationError(refused)
        W = d.W
        self.x, self.u_n, self.u = fem.Function(W), fem.Function(W), fem.Function(W)
        w, du = ufl.TestFunction(W), ufl.TrialFunction(W)
        try:        # a problem's own psi that fails or is not a scalar: the input refused, as a refusal is
            f_int = algorithmic.internal_force(m, kind, self.x, self.u_n, w, p)
            energy = algorithmic.energy_density(m, self.u, p)
        except materials.MaterialError as e:
            raise DiscretisationError(str(e)) from None
        self.degree = q = degree(d)
        self._force_form = compat.form(f_int, quadrature_degree=q)
        self._tangent_form = compat.form(ufl.derivative(f_int, self.x, du), quadrature_degree=q)
        self._energy_form = compat.form(energy * ufl.dx, quadrature_degree=q)
        self._force = compat.assemble_vector(self._force_form)
        self.nW = d.A.getLocalSize()[0]
        self._check_rest()

    def _set(self, f, vec):
        """f <- the owned values of ``vec`` (a vector of W^h's layout), ghosts updated."""
        f.x.array[:self.nW] = vec.array_r
        f.x.scatter_forward()

    def force(self, X, Un, out):
        """out <- int P_alg(X; U^n) : grad w dx at every owned dof (collective)."""
        self._set(self.x, X)
        self._set(self.u_n, Un)
        compat.assemble_vector_into(self._force, self._force_form)
        out.array[:] = self._force.array_r[:self.nW]
        return out

    def tangent(self, X, Un):
        """The tangent d F_int / dX at (X; U^n), a new assembled matrix (collective)."""
        self._set(self.x, X)
        self._set(self.u_n, Un)
        return compat.assemble_matrix(self._tangent_form)

    def energy(self, U):
        """int psi(C(U)) dx (collective)."""
        self._set(self.u, U)
        return self.discretisation.comm.allreduce(float(fem.assemble_scalar(self._energy_form)), op=MPI.SUM)

    def _check_rest(self):
        """DiscretisationError unless the tangent at U = 0 is the Problem's A at this degree (module
        docstring)."""
        d = self.discretisation
        zero = d.A.createVecRight()
        T0 = self.tangent(zero, zero)
        u, w = ufl.TrialFunction(d.W), ufl.TestFunction(d.W)
        A = compat.assemble_matrix(compat.form(d.problem.a(u, w), quadrature_degree=self.degree))
        T0.axpy(-1.0, A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        scale = A.norm(PETSc.NormType.FROBENIUS)
        A.destroy()
        rel = T0.norm(PETSc.NormType.FROBENIUS) / scale if scale > 0 else float("inf")
        T0.destroy()
        zero.destroy()
        if not rel <= REST_TOL:
            raise DiscretisationError(
                f"material {self.material.name!r}: its tangent at rest differs from problem "
                f"{d.problem.name!r}'s a(u, w) by {rel:.2g} (relative), so the problem's bilinear form is not this "
                f"material's linearisation (other Lame parameters, plane stress or an extra term it would drop): "
                f"refused rather than run a different model")

    def destroy(self):
        self._force.destroy()
