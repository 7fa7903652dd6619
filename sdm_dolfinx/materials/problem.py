"""The Problem's own strain energy: ``Problem.strain_energy(C)``, psi as a UFL expression of the right
Cauchy-Green tensor C (a problem file's material; docs/finite_strain.md).

Written in C rather than F, psi is objective by construction, which the energy-momentum scheme's
conservation of the angular momentum needs. The run checks that psi linearises at C = I to the
Problem's own a(u, w) (:mod:`sdm_dolfinx.method.finite_strain`), so a psi and an a(u, w) that
disagree are refused rather than run.
"""
from sdm_dolfinx.materials.base import Material, MaterialError


class ProblemMaterial(Material):
    name = "problem"
    help = "the problem's own strain_energy(C) (a problem file's psi; general: Gonzalez's discrete gradient)"

    def refusal(self, problem):
        if getattr(problem, "strain_energy", None) is None:
            return (f"material 'problem' is the problem's own strain energy, and problem {problem.name!r} declares "
                    f"none (Problem.strain_energy = lambda C: psi): choose svk or neo-hookean")
        shape, gdim = tuple(problem.shape), problem.mesh.geometry.dim
        if len(shape) != 1 or shape[0] != gdim or gdim < 2:
            return (f"material 'problem' is a hyperelastic law of a vector displacement in 2-D or 3-D; problem "
                    f"{problem.name!r} solves another field: use material 'linear'")
        return None

    def psi(self, C, problem):
        try:
            psi = problem.strain_energy(C)
        except Exception as e:          # the problem file's own code: one line naming it, not a traceback
            raise MaterialError(f"problem {problem.name!r}: strain_energy(C) failed: {type(e).__name__}: "
                                f"{str(e).splitlines()[0] if str(e) else ''}") from None
        if getattr(psi, "ufl_shape", None) != ():
            raise MaterialError(f"problem {problem.name!r}: strain_energy(C) must return a scalar UFL expression "
                                f"of C (got {type(psi).__name__} of shape {getattr(psi, 'ufl_shape', '?')})")
        return psi


MATERIAL = ProblemMaterial()
