"""Backward Euler: X = U^{n+1}, alpha = 1/dt, Vbar^{n+1} = (U^{n+1} - U^n)/dt.

Dissipative (first order); the constraint holds exactly at the end of each step. The
equation holds at t_{n+1}: a time-dependent load enters as L(t_{n+1}), a moving bound as
U^{n+1} >= g(t_{n+1}).
"""
from sdm_dolfinx.schemes.base import Scheme


class BackwardEuler(Scheme):
    name = "backward-euler"
    factor = 1.0
    constrained = "U^{n+1}"
    load_theta = 1.0                # L(t_{n+1})
    bound_weight = 1.0              # U^{n+1} >= g(t_{n+1})

    def displacement(self, x, Un):
        return x

    def velocity(self, x, Un, Vn, alpha):
        return alpha * (x - Un)

    def velocity_block(self, y, Vn):
        return y


SCHEME = BackwardEuler()
