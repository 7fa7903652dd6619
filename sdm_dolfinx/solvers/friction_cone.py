"""The frictional step solver in 3-D: the friction cone is a disc at every contact vertex.

At each contact vertex i there is a normal dof and two tangential ones; the tangential
reaction lam_T,i is a 2-vector and d_i = x_t,i - xref_i the 2-vector slip of the step (the
conventions of :mod:`sdm_dolfinx.solvers.friction_newton`, r = K x - b the obstacle's reaction):

    |lam_T| <= g,   |lam_T| < g  =>  d = 0,   d != 0  =>  lam_T = -g d / |d|

with g = s (Tresca) or mu lam_N (Coulomb). Alart–Curnier's function is the projection onto
the disc, lam_T = P_g(z), z = lam_T - c_t d: stick where |z| <= g, slip (lam_T = g z / |z|)
elsewhere. The semi-smooth Newton method of S. Hüeber, G. Stadler, B. Wohlmuth, SIAM J. Sci.
Comput. 30 (2008) 572–596, Section 3 (the 3-D slip set): on the slip set the condition is
written |z| lam_T - g z = 0 and linearised at the iterate,

    (|z| I + lam~ z^^T - g I) lam_T^+ - c_t (lam~ z^^T - g I) d^+ [- mu z lam_N^+] = |z| lam~ [- g z],

(z^ = z / |z|; lam~ = lam_T scaled into the disc of radius g, HSW's damping of the Jacobian;
the bracketed Coulomb terms linearise g = mu lam_N), two rows per slip vertex that couple its
two tangential components; stick vertices have x_t = xref, active ones x_n = lb. Each
iteration is one small dense non-symmetric system on cached columns of K^-1
(:meth:`~sdm_dolfinx.solvers.friction_system.FrictionSystem.cone`): K is factorised once per
run, as in 2-D. c_t = k_t (the mean diagonal of K at the tangential dofs) by default.

At convergence (the 2-D tests with |.|: stick |lam_T| <= g + tol; a slip vertex with
|d| > tol / k_t has |lam_T + g d / |d|| <= tol) lam_T . d = -g |d| <= 0 to the tolerance at
every vertex, so :mod:`sdm_dolfinx.contact.friction`'s energy argument holds as in 2-D.

Measured (``tests/physics/test_ball_friction.py``, :mod:`sdm_dolfinx.validation.ball_oblique`: the
ball at level 1, v = vt = 100 mm/s, mu = 0.02 .. 1, 125 steps, ~20 vertices in contact at the peak; and
an elastic box sticking or sliding): 2.3-3.2 iterations per contact step on average, at most 6;
no failure. Two simpler iterations failed on the same ball (mu = 0.3) and were dropped: a fixed
point on the slip direction inside each system (sigma := -d / |d|, lam_T = g sigma) cycled
at a vertex on the stick/slip boundary, whose tiny slip turns with a small change of its
force; and Newton on lam_T = -g d / |d| (the c_t -> 0 limit, curvature g / |d|) overshot
there and cycled between stick and slip.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.friction_newton import FrictionalNewton


#: the default tangential Alart–Curnier parameter c_t, times the mean diagonal of K at the
#: tangential dofs (k_t)
C_T_FACTOR = 1.0


def _unit(v, fallback):
    """v / |v| row-wise, ``fallback`` where v = 0."""
    n = np.linalg.norm(v, axis=1)
    return np.where(n[:, None] > 0.0, v / np.where(n > 0.0, n, 1.0)[:, None], fallback)


class FrictionalNewtonCone(FrictionalNewton):
    """:class:`FrictionalNewton` for 3-D contact: ``tdofs`` is m x 2 (the two tangential dofs of
    each contact vertex), ``lam_t`` m x 2 after :meth:`solve`, ``xref_t`` m x 2. ``c_t`` = 0 (the
    default) means :data:`C_T_FACTOR` k_t. Everything else (arguments, ``coulomb`` methods,
    Murty's rule against cycles) as the 2-D solver."""

    def __init__(self, K, ndofs, tdofs, lb, **kwargs):
        tdofs = np.asarray(tdofs, dtype=np.int32)
        if tdofs.ndim != 2 or tdofs.shape[1] != 2:
            raise ValueError(f"3-D friction needs m x 2 tangential dofs, not shape {tdofs.shape}")
        super().__init__(K, ndofs, tdofs, lb, **kwargs)
        if self.c_t == 0.0:
            self.c_t = C_T_FACTOR * self.k_t

    def _initial_sigma(self):
        return np.zeros((self.m, 2))

    def _predict(self, xn, lamN, lamT, d, sets, s):
        """The sets the Alart–Curnier functions select at an iterate: (active, stick, z) with
        z = lam_T - c_t d (stick where |z| <= g, g = s or mu max(0, lam_N - c_n (x_n - lb)))."""
        lt = lamN - self.c_n * (xn - self.lb)
        active = lt > 0.0
        g = self.mu * np.maximum(lt, 0.0) if s is None else s
        z = lamT - self.c_t * d
        stick = (np.linalg.norm(z, axis=1) <= g) & (g > 0.0)
        return active, stick, z

    def _linearised(self, lamN, lamT, z, s):
        """(A, B, e, q) of :meth:`FrictionSystem.cone` at the iterate (lam_N, lam_T) with
        z = lam_T - c_t d: Newton's linearisation of |z| lam_T - g z = 0 (the slip condition
        lam_T = g z / |z| times |z|), with lam_T replaced by its projection onto the disc of
        radius g in the derivative (HSW's damping) and, for Coulomb, g = mu lam_N linearised."""
        m, c = self.m, self.c_t
        zn = np.linalg.norm(z, axis=1)
        zh = _unit(z, 0.0)
        g = self.mu * np.maximum(lamN, 0.0) if s is None else s
        ln = np.linalg.norm(lamT, axis=1)
        lt = lamT * (g / np.maximum(ln, g, where=ln > 0, out=np.where(ln > 0, ln, 1.0)))[:, None]
        lz = np.einsum("ia,ib->iab", lt, zh)                     # lam~ zhat^T
        eye = np.broadcast_to(np.eye(2), (m, 2, 2))
        A = zn[:, None, None] * eye + lz - g[:, None, None] * eye
        B = -c * (lz - g[:, None, None] * eye)
        q = lt * zn[:, None]
        if s is None:
            return A, B, -self.mu[:, None] * z, q - g[:, None] * z
        return A, B, np.zeros((m, 2)), q

    def _newton(self, xref, tol, s, max_it=None):
        """The semi-smooth Newton iterations of one step (s: Tresca thresholds; None: Coulomb).
        Murty's rule as in 2-D. Returns ``{"its"}``."""
        m, (active, stick, z) = self.m, self._sets
        lamN, lamT = self.lam, self.lam_t
        murty = MurtyRule(self.K.getOwnershipRange()[0] + self.ndofs, self.comm)
        max_it = max_it or self.max_it
        for it in range(1, max_it + 1):
            friction = active if s is None else np.ones(m, dtype=bool)
            stick = stick & friction
            slip = friction & ~stick
            A, B, e, q = self._linearised(lamN, lamT, z, s)
            xc, r = self.system.cone(active, stick, slip, self.lb, xref, A, B, e, q)
            xn, lamN = xc[:m], r[:m]
            d = xc[m:].reshape(2, m).T - xref
            lamT = r[m:].reshape(2, m).T
            g = np.where(friction, self.mu * lamN if s is None else s, 0.0)
            dn, ln = np.linalg.norm(d, axis=1), np.linalg.norm(lamT, axis=1)
            moving = slip & (dn > tol / self.k_t)
            bad_n = np.where(active, lamN < -tol, xn < self.lb - tol / self.c_n)
            off = np.linalg.norm(lamT + g[:, None] * d / np.where(dn > 0.0, dn, 1.0)[:, None], axis=1)
            bad_t = np.where(stick, ln > g + tol, np.where(moving, off > tol, slip & (ln > g + tol)))
            n_bad = self.comm.allreduce(int(np.count_nonzero(bad_n | bad_t)), op=MPI.SUM)
            self.lam, self.lam_t = lamN, lamT
            self.active, self.stick, self.slip = active, stick, slip & (g > 0.0)
            if self.monitor and self.comm.rank == 0:
                print(f"  {it:3d} frictional Newton (3-D): {n_bad} conditions violated (tolerance {tol:.3e})",
                      flush=True)
            new = self._predict(xn, lamN, lamT, d, (active, stick, z), s)
            self._sets = (active, stick, new[2])
            if n_bad == 0:
                return {"its": it}
            one = murty.single(n_bad, bad_n | bad_t)
            if one is not None:
                normal = one & bad_n
                tangential = one & ~bad_n | (normal if s is None else False)
                new = (np.where(normal, new[0], active), np.where(tangential, new[1], stick), new[2])
            active, stick, z = new
        raise VIError(f"frictional semi-smooth Newton in 3-D ({'Coulomb' if s is None else 'Tresca'}) did not "
                      f"converge in {max_it} iterations ({n_bad} conditions still violated)")
