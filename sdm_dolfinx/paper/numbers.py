"""The paper's own numbers beyond the time series: the counting condition of (7) on the
membrane, the rates of the disc's H¹ convergence as Table 2 fits them (Fig. 16; the errors are
:mod:`.table2`'s) and the energy recomputed from the stored fields of a few runs."""
from mpi4py import MPI

from sdm_dolfinx import post
from sdm_dolfinx.paper.design import MEMBRANE_PAIRS, PAPER_TABLE2

COMM = MPI.COMM_WORLD


# ------------------------------------------------------------------- condition (7) counts
def counting_condition(pair, N):
    """(dim H^h, dim W^h_0 - N_g) for the membrane on N x N squares; condition (7) needs
    dim H^h <= dim W^h - N_g (section 2), W^h without the Dirichlet dofs and H^h with all its dofs."""
    ng = (N - 1) ** 2
    w = {"P1": (N - 1) ** 2, "P1+": (N - 1) ** 2 + 2 * N * N, "P2": (2 * N - 1) ** 2}[pair.split("/")[0]]
    h = {"P0": 2 * N * N, "P1": (N + 1) ** 2, "P2": (2 * N + 1) ** 2}[pair.split("/")[1]]
    if pair.split("/")[0] == pair.split("/")[1]:
        h = w                                       # standard Galerkin: H^h = W^h
    return h, w - ng


def counts_ok(pair, N):
    h, room = counting_condition(pair, N)
    return h <= room


# ------------------------------------------------------- the disc's convergence rates
def fit_rates(levels, ref_level, errors, semi, dofs):
    """Convergence rates of the H1 errors against the nominal h of Table 2 (h halves per level).

    ``rate`` fits the levels the way the paper did: it left out the level next to its
    reference (h = 0.14 mm, "too close to the reference"), when at least two remain.
    """
    coarse = [lev for lev in levels if lev != ref_level]
    h = {lev: PAPER_TABLE2[lev][1] if lev in PAPER_TABLE2 else 2.0 / 2 ** (lev - 1) for lev in levels}
    fit = [lev for lev in coarse if lev != ref_level - 1] if len(coarse) >= 3 else coarse
    rate = post.convergence_rate([h[x] for x in fit], [errors[x] for x in fit])
    return {"h_nominal": h, "fit_levels": fit, "rate": rate,
            "rate_all_levels": post.convergence_rate([h[x] for x in coarse], [errors[x] for x in coarse]),
            "rate_from_dofs": -2 * post.convergence_rate([dofs[x] for x in coarse], [errors[x] for x in coarse]),
            "rate_seminorm": post.convergence_rate([h[x] for x in fit], [semi[x] for x in fit])}


# ------------------------------------------------------------------------ energy checks
def energy_checks(study, runs_dir, comm=COMM):
    """The energy recomputed from state.h5 against timeseries.csv, for a few runs (collective)."""
    runs = [study.pairs[p][1e-3] for p in MEMBRANE_PAIRS] + [study.disc["P2/P1"][1e-4]]
    out = []
    for r in runs:
        res = post.recompute_energy(runs_dir / r.name, comm)
        out.append({"run": r.name, "states": int(len(res["step"])), "max_rel_diff": res["max_rel_diff"],
                    "max_roundoff_ratio": res["max_roundoff_ratio"], "stored_dtype": res["stored_dtype"]})
    return out
