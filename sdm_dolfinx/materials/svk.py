"""Saint Venant-Kirchhoff: psi = lambda/2 (tr E)^2 + mu E : E, S = lambda tr(E) I + 2 mu E.

Hooke's law written in E instead of the linear strain: exact for large rotations, soft in
compression (it is not polyconvex: a bar compressed to 1/sqrt(3) of its length loses its
stiffness). Quadratic in E, so the energy-momentum scheme's stress S(E_mid) conserves the energy
exactly (Simo and Tarnow 1992).
"""
from sdm_dolfinx.materials.base import Material, green_lagrange

import ufl


class SaintVenantKirchhoff(Material):
    name = "svk"
    help = "Saint Venant-Kirchhoff: psi = lambda/2 (tr E)^2 + mu E:E (large rotations, moderate strains)"
    quadratic = True

    def psi(self, C, problem):
        lam, mu = self.lame(problem)
        E = green_lagrange(C)
        return 0.5 * lam * ufl.tr(E) ** 2 + mu * ufl.inner(E, E)


MATERIAL = SaintVenantKirchhoff()
