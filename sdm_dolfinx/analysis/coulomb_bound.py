"""How large a Coulomb coefficient the frictional step problem stands (``inspect --coulomb-bound``).

A step with every constrained vertex in contact and slipping (directions sigma_i = +-1) fixes
x_n = lb and lam_T = -mu sigma lam_N (contact/friction.py's convention), so with the compliance
of the step matrix at the contact dofs, G = E^T K^-1 E (normal block G_nn, coupling G_nt), the
normal reactions solve

    N(mu, sigma) lam_N = rhs,        N = G_nn - mu G_nt diag(sigma).

G_nn is SPD (a principal block of K^-1, K = alpha^2 M + A SPD: for the (U, V) block system its
Schur complement), so N is too at mu = 0; the symmetric part of N stays positive definite, which
makes the step's contact problem uniquely solvable (a P-matrix) and keeps the Newton systems
regular, for

    mu < mu_c(sigma) = 1 / lambda_max(L^-1 sym(G_nt diag sigma) L^-T),    G_nn = L L^T

(+inf when that eigenvalue is <= 0). A principal block of a positive definite matrix is positive
definite, so the bound also covers every subset of the vertices in contact with the same slip
directions. :func:`coulomb_bound` measures mu_c for a uniform slip (sigma = +1 and -1) and the
worst of random directions; it is a sufficient condition, not a sharp one, for the all-slip
configurations (mixed stick/slip sets are not covered). K depends on dt (alpha = factor / dt),
so the bound is the pair's, the mesh's and the time step's.
"""
import numpy as np

from sdm_dolfinx.contact.friction_bound import SAMPLES, compliance, measure, mu_critical  # noqa: F401
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.contact.friction import Friction
from sdm_dolfinx.run.integrator import Integrator


def coulomb_bound(problem, pair, dt, scheme="midpoint", mass=None, samples=SAMPLES, seed=0):
    """The Coulomb bound of ``problem`` with ``pair``, ``scheme`` and ``dt`` (collective).

    Returns a dict: ``mu_uniform`` (min over sigma = +1, -1), ``mu_random`` (min over
    ``samples`` random patterns, the same on every rank), ``mu_c`` (the smaller), the number
    of contact vertices, dt and the scheme.
    """
    if tuple(problem.shape) == (3,):
        raise DiscretisationError(f"--coulomb-bound is derived for 2-D problems (one tangential direction), not "
                                  f"for problem {problem.name!r} (3 components: a disc-shaped friction cone)")
    if getattr(problem, "obstacles", None):
        raise DiscretisationError(f"--coulomb-bound is derived for the axis-aligned bound (the normal along one axis), "
                                  f"not for the obstacles of problem {problem.name!r} (each node's normal its own): "
                                  f"not measured yet")
    d = Discretisation(problem, pair, mass)
    integ = Integrator(d, scheme, dt, friction=Friction("coulomb", mu=0.0))
    try:
        r = measure(integ, samples, seed)
    finally:
        integ.destroy()
    return {"pair": d.pair.name, "dt": dt, "scheme": scheme, **r}


def bound_line(r):
    """One line of text for a :func:`coulomb_bound` result."""
    if not r["vertices"]:
        return f"{r['pair']}: no constrained vertices: no Coulomb bound"
    fmt = lambda v: "none (any mu)" if not np.isfinite(v) else f"{v:.3g}"
    return (f"{r['pair']}: Coulomb step problem (all {r['vertices']} constrained vertices in contact and slipping, "
            f"dt = {r['dt']:g}, {r['scheme']}): its Newton matrix stays positive definite for mu < "
            f"{fmt(r['mu_c'])} (uniform slip: {fmt(r['mu_uniform'])}; worst of {SAMPLES} random slip "
            f"directions: {fmt(r['mu_random'])})")
