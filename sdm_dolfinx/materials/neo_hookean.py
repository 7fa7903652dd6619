"""Compressible neo-Hookean: psi = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2, J = det F.

In 2-D (plane strain, C_33 = 1) tr C - 3 is tr C - 2 of the in-plane C. The stress
S = mu (I - C^-1) + lambda ln(J) C^-1 is Hooke's law at F = I and stiffens without bound as
J -> 0 (no element is turned inside out). Not quadratic: the energy-momentum scheme takes
Gonzalez's discrete gradient (:mod:`.algorithmic`).
"""
from sdm_dolfinx.materials.base import Material, dimension

import ufl


class NeoHookean(Material):
    name = "neo-hookean"
    help = "compressible neo-Hookean: psi = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2 (rubber, large strains)"

    def psi(self, C, problem):
        lam, mu = self.lame(problem)
        lnJ = 0.5 * ufl.ln(ufl.det(C))
        return 0.5 * mu * (ufl.tr(C) - dimension(C)) - mu * lnJ + 0.5 * lam * lnJ ** 2


MATERIAL = NeoHookean()
