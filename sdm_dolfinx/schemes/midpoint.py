"""The midpoint scheme (paper eq. (14), (23)): X = U^{n+1/2}, alpha = 2/dt.

U^{n+1} = 2 X - U^n and Vbar^{n+1} = 2 alpha (X - U^n) - Vbar^n = 2 (U^{n+1} - U^n)/dt - Vbar^n.
It conserves the discrete energy J^h without impact (Theorem 2) and constrains the
midpoint, so U^{n+1} itself may dip below the bound: by O(dt) when U^0 is static on the singular
mass's massless modes, by O(h) whatever dt when it is not (the midpoint rule's stability function
is -1 at infinity: such a mode alternates, validation/rod_contact.py). The equation of (14) holds at
t_{n+1/2}: a time-dependent load enters as L(t_{n+1/2}) (second order).

Prescribed displacements (a Problem's Dirichlet parts, u = u_D(x, t)): the unknown X = U^{n+1/2}
takes (U^n + u_D(t_{n+1}))/2 at the part's dofs, which is (u_D(t_n) + u_D(t_{n+1}))/2 since U^0 =
u_D(0) there, so that U^{n+1} = 2 X - U^n = u_D(t_{n+1}) exactly at every step (u_D(t_{n+1/2})
instead would make U^{n+1} drift from the data by O(dt^2) per step). The velocity there follows
the scheme's own rule, (V^n + V^{n+1})/2 = (U^{n+1} - U^n)/dt. The part's reaction R (the
residual K X - b at its rows: M (Vbar^{n+1} - Vbar^n)/dt + A U^{n+1/2} - L) then enters the
same identity as the contact force, so that

    J^{n+1} - J^n = (lam + R) . (U^{n+1} - U^n),

and with W_D the sum over the steps of R . (U^{n+1} - U^n) (the column ``dirichlet_work``),
J - W_D is conserved to round-off without impact (tests/physics/test_prescribed_motion.py).

A moving obstacle (``Problem.moving_bound``: u_c(a_i) >= g_i(t)) is imposed as
U^{n+1/2}_i >= (g_i(t_n) + g_i(t_{n+1})) / 2, the mean of the bounds, not g_i(t_{n+1/2}). Why:
the step's equation M (Vbar^{n+1} - Vbar^n) / dt + A U^{n+1/2} = L + lam, multiplied by
U^{n+1} - U^n = dt (Vbar^{n+1} + Vbar^n) / 2, gives exactly (L constant)

    E^{n+1} - E^n = lam . (U^{n+1} - U^n),    E = 1/2 Vbar^T M Vbar + 1/2 U^T A U - L^T U.

Where lam_i > 0, U^{n+1/2}_i equals the step's bound b_i, so U^{n+1}_i = 2 b_i - U^n_i. A vertex
on the obstacle at t_n (U^n_i = g_i(t_n)) is on it at t_{n+1} (U^{n+1}_i = g_i(t_{n+1})) if and
only if b_i = (g_i(t_n) + g_i(t_{n+1})) / 2; then lam_i (U^{n+1}_i - U^n_i) = lam_i (g_i(t_{n+1}) -
g_i(t_n)), and by induction in sustained contact (started on the obstacle, as from rest in
contact or an equilibrium start)

    E^{n+1} - E^n = sum_i lam_i (g_i(t_{n+1}) - g_i(t_n)) = W^{n+1} - W^n,

the column ``obstacle_work`` W: E - W is conserved to round-off. With b_i = g_i(t_{n+1/2}) instead,
U^{n+1}_i - g_i(t_{n+1}) alternates in sign with the amplitude 2 |g(t_{n+1/2}) - mean| ~ dt^2 |g''| / 4
(exact for a wall at constant velocity, where both are equal), and so does E - W. A vertex that
arrives on a moving obstacle (an impact) loses energy as on a fixed one.
"""
from sdm_dolfinx.schemes.base import Scheme
from sdm_dolfinx.solvers.active_set import MULTIGRID_STRATEGIES


class Midpoint(Scheme):
    name = "midpoint"
    factor = 2.0
    constrained = "U^{n+1/2}"
    load_theta = 0.5                # L(t_{n+1/2})
    moving_dirichlet = True
    finite_strain = "energy-momentum"     # a hyperelastic material: P_alg of sdm_dolfinx.materials.algorithmic

    def dirichlet_iterate(self, u_next, Un):
        """X = (U^n + u_D(t_{n+1}))/2: U^{n+1} = 2 X - U^n = u_D(t_{n+1}) exactly (module docstring)."""
        return 0.5 * (u_next + Un)
    bound_weight = 0.5              # U^{n+1/2} >= (g(t_n) + g(t_{n+1})) / 2 (see the module)

    def displacement(self, x, Un):
        return 2.0 * x - Un

    def velocity(self, x, Un, Vn, alpha):
        return 2.0 * alpha * (x - Un) - Vn

    def velocity_block(self, y, Vn):
        return 2.0 * y - Vn

    def guess(self, integ, U, V, X):
        """U^n; with a multigrid strategy (whose Krylov iterations start from the guess) the predictor
        U^n + Vbar^n / alpha, which is X when Vbar^{n+1} = Vbar^n: in flight its error is O(dt^2) where
        U^n's is O(dt). The ball (level 3, 6 steps, cg-pmg): 22 % less time (bench/README.md). A hyperelastic run
        starts from U^n: on the singular mass's massless modes Vbar^n alternates in sign (the midpoint rule's
        stability function is -1 at infinity), and the predictor, moved by it, took a neo-Hookean step's Newton
        iterations out of their basin (P2/P1, a square spinning from a strained U^0: no convergence at step 20,
        against 2 iterations per step from U^n)."""
        super().guess(integ, U, V, X)
        if integ.linear_strategy in MULTIGRID_STRATEGIES and not integ.block:
            X.array[:integ.nW] += V.array_r / integ.alpha


SCHEME = Midpoint()
