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

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.contact.friction import Friction
from sdm_dolfinx.run.integrator import Integrator

#: random slip-direction patterns tried besides the two uniform ones
SAMPLES = 64


def compliance(integ):
    """(G_nn, G_nt) on every rank: K^-1 at the contact dofs (one solve per contact dof)."""
    solver = integ.solver
    comm, K = solver.comm, integ.K
    r0 = K.getOwnershipRange()[0]
    nd = np.concatenate(comm.allgather(r0 + solver.ndofs))
    td = np.concatenate(comm.allgather(r0 + solver.tdofs))
    e, z = K.createVecLeft(), K.createVecRight()
    cols = []
    for g in np.concatenate([nd, td]):
        e.set(0.0)
        if r0 <= g < r0 + e.getLocalSize():
            e.array[g - r0] = 1.0
        solver.fac.solve(e, z)
        cols.append(np.concatenate(comm.allgather(np.r_[z.array_r[solver.ndofs], z.array_r[solver.tdofs]])))
    Z = np.array(cols).T                             # rows: n dofs then t dofs of every rank, in order
    m = len(nd)
    counts = comm.allgather(len(solver.ndofs))
    order_n = np.concatenate([o + np.arange(c) for o, c in zip(np.r_[0, np.cumsum(counts)[:-1]] * 2, counts)])
    order_t = order_n + np.repeat(counts, counts)
    G = Z[np.r_[order_n, order_t]]
    return G[:m, :m], G[:m, m:]


def mu_critical(Gnn, Gnt, sigma):
    """mu_c(sigma) of the module's docstring."""
    L = np.linalg.cholesky(0.5 * (Gnn + Gnn.T))
    S = Gnt * sigma[None, :]
    S = 0.5 * (S + S.T)
    Li = np.linalg.inv(L)
    top = float(np.linalg.eigvalsh(Li @ S @ Li.T).max())
    return np.inf if top <= 0 else 1.0 / top


def coulomb_bound(problem, pair, dt, scheme="midpoint", mass=None, samples=SAMPLES, seed=0):
    """The Coulomb bound of ``problem`` with ``pair``, ``scheme`` and ``dt`` (collective).

    Returns a dict: ``mu_uniform`` (min over sigma = +1, -1), ``mu_random`` (min over
    ``samples`` random patterns, the same on every rank), ``mu_c`` (the smaller), the number
    of contact vertices, dt and the scheme.
    """
    if tuple(problem.shape) == (3,):
        raise DiscretisationError(f"--coulomb-bound is derived for 2-D problems (one tangential direction), not "
                                  f"for problem {problem.name!r} (3 components: a disc-shaped friction cone)")
    d = Discretisation(problem, pair, mass)
    integ = Integrator(d, scheme, dt, friction=Friction("coulomb", mu=0.0))
    try:
        Gnn, Gnt = compliance(integ)
    finally:
        integ.destroy()
    m = len(Gnn)
    if m == 0:
        return {"pair": d.pair.name, "vertices": 0, "mu_c": None, "dt": dt, "scheme": scheme}
    uniform = min(mu_critical(Gnn, Gnt, s * np.ones(m)) for s in (1.0, -1.0))
    rng = np.random.default_rng(seed)
    rand = min((mu_critical(Gnn, Gnt, rng.choice([-1.0, 1.0], m)) for _ in range(samples)), default=np.inf)
    return {"pair": d.pair.name, "vertices": m, "dt": dt, "scheme": scheme, "mu_uniform": uniform,
            "mu_random": rand, "mu_c": min(uniform, rand)}


def bound_line(r):
    """One line of text for a :func:`coulomb_bound` result."""
    if not r["vertices"]:
        return f"{r['pair']}: no constrained vertices: no Coulomb bound"
    fmt = lambda v: "none (any mu)" if not np.isfinite(v) else f"{v:.3g}"
    return (f"{r['pair']}: Coulomb step problem (all {r['vertices']} constrained vertices in contact and slipping, "
            f"dt = {r['dt']:g}, {r['scheme']}): its Newton matrix stays positive definite for mu < "
            f"{fmt(r['mu_c'])} (uniform slip: {fmt(r['mu_uniform'])}; worst of {SAMPLES} random slip "
            f"directions: {fmt(r['mu_random'])})")
