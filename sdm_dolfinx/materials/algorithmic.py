"""The internal force of a step: int P_alg : grad w dx, P_alg the stress a time scheme evaluates.

Two kinds, named by the scheme (:attr:`Scheme.finite_strain <sdm_dolfinx.schemes.base.Scheme.finite_strain>`):

``endpoint`` (backward Euler, X = U^{n+1}): P_alg = F(X) S(C(X)), the stress at the end of the step.

``energy-momentum`` (the midpoint scheme, X = U^{n+1/2}, U^{n+1} = 2 X - U^n). With F_0, F_1 the
deformation gradients at t_n and t_{n+1}, F_mid = (F_0 + F_1)/2 = I + grad X, C_i = F_i^T F_i,
dC = C_1 - C_0 and C_mid = (C_0 + C_1)/2:

    P_alg = F_mid S_alg,   S_alg = S(C_mid) + 2 [psi(C_1) - psi(C_0) - S(C_mid) : dC / 2] dC / (dC : dC).

Why it conserves energy: sym(F_mid^T (F_1 - F_0)) = (C_1 - C_0)/2 exactly (expand the products), so
at every quadrature point

    P_alg : grad(U^{n+1} - U^n) = S_alg : dC / 2 = psi(C_1) - psi(C_0),

and the step's equation M (Vbar^{n+1} - Vbar^n)/dt + F_int = L + lam, multiplied by U^{n+1} - U^n =
dt (Vbar^{n+1} + Vbar^n)/2, gives J^{n+1} - J^n = lam . (U^{n+1} - U^n) with J = 1/2 Vbar^T M Vbar +
int psi(C(U)) dx - L^T U, the linear scheme's identity (paper, Theorem 2) with psi in place of
1/2 a(u, u): without contact J is conserved to the tolerance of the step's Newton iterations, and
the contact enters as before. The bracket is Gonzalez's (2000) discrete-gradient correction; for a
psi quadratic in E (Saint Venant-Kirchhoff) it vanishes identically and S_alg = S(E_mid) is Simo
and Tarnow's (1992) stress, which is used as such.

The bracket is O(|dC|^3), and psi(C_1) - psi(C_0) carries the rounding of psi's terms, about eps mu
whatever the strain (det C and tr C are near 1 and d): divided by |dC|, that put a noise of 1e-8 of the stress
into a neo-Hookean block's internal force at |dC| = 1e-5 (measured: a relative change of 1e-13 in X moved the
force by 4e-9 where Saint Venant-Kirchhoff's moved by 2e-12), and its Newton iterations stalled at a residual
of 1e-8. So where |dC| < :data:`SWITCH` the bracket is computed without the difference of psi: as
psi(C_1) - psi(C_0) = int_0^1 S(C(s)) : dC / 2 ds along C(s) = C_0 + s dC,

    psi(C_1) - psi(C_0) - S(C_mid) : dC / 2 = 1/4 sum_k w_k (S(C_mid + xi_k dC / 2) - S(C_mid)) : dC

with the 4-point Gauss-Legendre rule (xi_k, w_k), exact to O(|dC|^9 psi^(9)), below 1e-18 of the stress
scale at |dC| = 1e-2, where the two forms of the bracket meet. The quotient 2 [...] dC / (dC : dC + DG_TOL)
is then accurate to eps |S| whatever |dC| (DG_TOL only keeps 0 / 0 at a point where dC = 0 from being
evaluated).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import ufl

from sdm_dolfinx.materials.base import Material

#: added to dC : dC in the discrete gradient's quotient (a point where dC = 0: 0 / DG_TOL = 0)
DG_TOL = 1e-30
#: below this |dC| the discrete gradient's bracket is integrated along the segment (module docstring)
SWITCH = 1e-2
#: the 4-point Gauss-Legendre rule on [-1, 1]
GAUSS = (np.polynomial.legendre.leggauss(4))
#: the kinds of internal force a scheme may name
KINDS = ("endpoint", "energy-momentum")
UFL = Any


def deformation_gradient(u: UFL) -> UFL:
    """F = I + grad u."""
    return ufl.Identity(len(u)) + ufl.grad(u)


def right_cauchy_green(u: UFL) -> UFL:
    """C = F^T F."""
    F = deformation_gradient(u)
    return F.T * F


def pk2(material: Material, C: UFL, problem: Any) -> UFL:
    """S = 2 dpsi/dC at C."""
    Cv = ufl.variable(C)
    return 2.0 * ufl.diff(material.psi(Cv, problem), Cv)


def energy_density(material: Material, u: UFL, problem: Any) -> UFL:
    """psi(C(u))."""
    return material.psi(right_cauchy_green(u), problem)


def stress(material: Material, kind: str, x: UFL, u_n: UFL, problem: Any) -> UFL:
    """P_alg of the step whose iterate is ``x`` from U^n = ``u_n`` (module docstring)."""
    if kind == "endpoint":
        return deformation_gradient(x) * pk2(material, right_cauchy_green(x), problem)
    if kind != "energy-momentum":
        raise ValueError(f"unknown internal force {kind!r}; choose one of {', '.join(KINDS)}")
    u1 = 2.0 * x - u_n
    C0, C1 = right_cauchy_green(u_n), right_cauchy_green(u1)
    C_mid, dC = 0.5 * (C0 + C1), C1 - C0
    S = pk2(material, C_mid, problem)
    if not material.quadratic:
        dd = ufl.inner(dC, dC)
        S = S + 2.0 * bracket(material, C0, C1, S, problem) / (dd + DG_TOL) * dC
    return deformation_gradient(x) * S


def bracket(material: Material, C0: UFL, C1: UFL, S_mid: UFL, problem: Any) -> UFL:
    """psi(C_1) - psi(C_0) - S_mid : dC / 2, by the difference of psi where |dC| >= SWITCH and along the
    segment (4-point Gauss) below it (module docstring)."""
    dC, C_mid = C1 - C0, 0.5 * (C0 + C1)
    direct = material.psi(C1, problem) - material.psi(C0, problem) - 0.5 * ufl.inner(S_mid, dC)
    xi, w = GAUSS
    along = 0.25 * sum(float(wk) * ufl.inner(pk2(material, C_mid + 0.5 * float(xk) * dC, problem) - S_mid, dC)
                       for xk, wk in zip(xi, w))
    return ufl.conditional(ufl.gt(ufl.inner(dC, dC), SWITCH ** 2), direct, along)


def internal_force(material: Material, kind: str, x: UFL, u_n: UFL, w: UFL, problem: Any) -> UFL:
    """int P_alg : grad w dx."""
    return ufl.inner(stress(material, kind, x, u_n, problem), ufl.grad(w)) * ufl.dx


def cauchy(material: Material, u: UFL, problem: Any) -> UFL:
    """The Cauchy stress sigma = F S F^T / J at the state u (in the reference configuration's
    coordinates: a field on the undeformed mesh)."""
    F = deformation_gradient(u)
    S = pk2(material, F.T * F, problem)
    return F * S * F.T / ufl.det(F)
