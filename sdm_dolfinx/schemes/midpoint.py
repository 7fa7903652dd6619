"""The midpoint scheme (paper eq. (14), (23)): X = U^{n+1/2}, alpha = 2/dt.

U^{n+1} = 2 X - U^n and Vbar^{n+1} = 2 alpha (X - U^n) - Vbar^n = 2 (U^{n+1} - U^n)/dt - Vbar^n.
It conserves the discrete energy J^h without impact (Theorem 2) and constrains the
midpoint, so U^{n+1} itself may dip below the bound: by O(dt) when U^0 is static on the singular
mass's massless modes, by O(h) whatever dt when it is not (the midpoint rule's stability function
is -1 at infinity: such a mode alternates, validation/rod_contact.py). The equation of (14) holds at
t_{n+1/2}: a time-dependent load enters as L(t_{n+1/2}) (second order).
"""
from sdm_dolfinx.schemes.base import Scheme


class Midpoint(Scheme):
    name = "midpoint"
    factor = 2.0
    constrained = "U^{n+1/2}"
    load_theta = 0.5                # L(t_{n+1/2})

    def displacement(self, x, Un):
        return 2.0 * x - Un

    def velocity(self, x, Un, Vn, alpha):
        return 2.0 * alpha * (x - Un) - Vn

    def velocity_block(self, y, Vn):
        return 2.0 * y - Vn


SCHEME = Midpoint()
