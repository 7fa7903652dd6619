"""The Coulomb coefficient a frictional step problem stands, measured on a step matrix and its
factorisation (the derivation: :mod:`sdm_dolfinx.analysis.coulomb_bound`, whose ``inspect
--coulomb-bound`` measures it before a run), and the words a failed Coulomb step adds: the bound,
measured then on the run's own factorised step matrix (2-D problems; one solve per contact dof),
and the command that measures it."""
import warnings

import numpy as np

#: random slip-direction patterns tried besides the two uniform ones
SAMPLES = 64
#: a failed Coulomb step measures the bound when the problem has at most this many constrained vertices
#: (2 solves per vertex with the run's factorisation, and 66 dense eigenvalue problems of that size)
FAILURE_MEASURE_MAX = 1000
#: before the first step the bound is measured (and a mu above it warned of) up to this many vertices:
#: 400 solves with the run's factorisation at most, a fraction of a second to a few seconds
UPFRONT_MEASURE_MAX = 200


class CoulombBoundWarning(UserWarning):
    """mu is above the Coulomb bound measured on the run's step problem (a sufficient bound: the run
    may still go through; if a step fails, its message names the bound again)."""


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


def measure(integ, samples=SAMPLES, seed=0):
    """``{"vertices", "mu_uniform", "mu_random", "mu_c"}`` of the frictional step solver of ``integ``
    (collective; see :func:`sdm_dolfinx.analysis.coulomb_bound.coulomb_bound`)."""
    Gnn, Gnt = compliance(integ)
    m = len(Gnn)
    if m == 0:
        return {"vertices": 0, "mu_c": None}
    uniform = min(mu_critical(Gnn, Gnt, s * np.ones(m)) for s in (1.0, -1.0))
    rng = np.random.default_rng(seed)
    rand = min((mu_critical(Gnn, Gnt, rng.choice([-1.0, 1.0], m)) for _ in range(samples)), default=np.inf)
    return {"vertices": m, "mu_uniform": uniform, "mu_random": rand, "mu_c": min(uniform, rand)}


def failure_hint(integ, mu, command):
    """What a failed Coulomb step of ``integ`` (its friction coefficient ``mu``) adds to its message:
    the bound measured now on the run's step matrix (2-D, at most :data:`FAILURE_MEASURE_MAX`
    constrained vertices) and ``command``, which measures it before a run (collective)."""
    solver = integ.solver
    m = solver.comm.allreduce(len(solver.ndofs))
    if np.ndim(solver.tdofs) != 1 or solver.frames or solver.rowwise:
        return ""               # 3-D (a disc-shaped cone), obstacles, the weighted gap: no bound derived
    if m > FAILURE_MEASURE_MAX:
        return f"; mu = {mu:g} may be above the Coulomb bound of this step problem: {command} measures it"
    try:
        r = measure(integ)
    except (np.linalg.LinAlgError, ValueError):    # a step matrix it cannot measure: say how to
        return f"; {command} measures the Coulomb bound of this step problem"
    bound = r["mu_c"]
    if bound is None or not np.isfinite(bound):
        return ""
    if mu > bound:
        return (f"; mu = {mu:g} is above {bound:.3g}, the largest Coulomb coefficient for which this step problem "
                f"is measured well-posed (every constrained vertex in contact and slipping: a sufficient bound, "
                f"measured before a run by {command}): try a smaller mu, or another dt or mesh")
    return f"; mu = {mu:g} is below this step problem's measured Coulomb bound {bound:.3g} ({command})"


def command_for(integ):
    """The ``inspect --coulomb-bound`` command that measures the bound of ``integ``'s run before a run."""
    p, d = integ.discretisation.problem, integ.discretisation
    which = f"--problem-file {p.source}" if p.source else f"--problem {p.name}"
    return (f"python -m sdm_dolfinx inspect {which} --pair {d.pair.name} --coulomb-bound --dt {integ.dt:g}"
            + (f" --scheme {integ.scheme}" if integ.scheme != "midpoint" else "") + " with the run's parameters")


def warn_if_above(integ, mu):
    """Before the first step: measure the Coulomb bound of ``integ``'s step problem (2-D, at most
    :data:`UPFRONT_MEASURE_MAX` constrained vertices; collective) and, when ``mu`` is above it, warn in
    one line (rank 0) naming the bound: the run may still go through, since the bound is sufficient,
    not sharp (a failed step names it again)."""
    solver = integ.solver
    m = solver.comm.allreduce(len(solver.ndofs))
    if np.ndim(solver.tdofs) != 1 or solver.frames or solver.rowwise or m == 0 or m > UPFRONT_MEASURE_MAX:
        return
    try:
        bound = measure(integ)["mu_c"]
    except (np.linalg.LinAlgError, ValueError):
        return
    if bound is None or not np.isfinite(bound) or mu <= bound or solver.comm.rank != 0:
        return
    # warn_explicit with no source file: one line ("sdm_dolfinx:0: CoulombBoundWarning: ...")
    warnings.warn_explicit(f"mu = {mu:g} is above {bound:.3g}, the Coulomb bound measured on this run's step "
                           f"problem (a sufficient bound: a step may fail to converge; {command_for(integ)} "
                           f"measures it before a run)", CoulombBoundWarning, "sdm_dolfinx", 0)


def step_hint(integ):
    """A failed step's hint: for Coulomb friction the Coulomb bound of the step problem, measured now,
    and the command that measures it before a run (:func:`failure_hint`); else '' (also for a hyperelastic
    run: the bound is the linear step matrix's, and its tangents change from iteration to iteration)."""
    if integ.friction is None or integ.friction.law != "coulomb" or getattr(integ, "finite_strain", None):
        return ""
    return failure_hint(integ, integ.friction.mu, command_for(integ))
