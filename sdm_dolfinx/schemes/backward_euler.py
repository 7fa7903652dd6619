"""Backward Euler: X = U^{n+1}, alpha = 1/dt, Vbar^{n+1} = (U^{n+1} - U^n)/dt.

Dissipative (first order); the constraint holds exactly at the end of each step. The
equation holds at t_{n+1}: a time-dependent load enters as L(t_{n+1}).
Prescribed displacements (a Problem's Dirichlet parts) enter at t_{n+1} too: X = U^{n+1} =
u_D(t_{n+1}) at the part's dofs; their reaction (the residual K X - b there) and its work
R . (U^{n+1} - U^n) are reported, and the scheme's dissipation makes J - W_D decrease.
A moving bound enters as U^{n+1} >= g(t_{n+1}).
"""
from sdm_dolfinx.schemes.base import Scheme


class BackwardEuler(Scheme):
    name = "backward-euler"
    factor = 1.0
    constrained = "U^{n+1}"
    load_theta = 1.0                # L(t_{n+1})
    moving_dirichlet = True
    finite_strain = "endpoint"          # a hyperelastic material: the stress at U^{n+1}

    def dirichlet_iterate(self, u_next, Un):
        """X = U^{n+1} = u_D(t_{n+1})."""
        return u_next
    bound_weight = 1.0              # U^{n+1} >= g(t_{n+1})

    def displacement(self, x, Un):
        return x

    def velocity(self, x, Un, Vn, alpha):
        return alpha * (x - Un)

    def velocity_block(self, y, Vn):
        return y


SCHEME = BackwardEuler()
