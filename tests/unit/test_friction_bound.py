"""``inspect --coulomb-bound`` (analysis/coulomb_bound.py): the compliance at the contact dofs
against a dense inverse of the step matrix, the bound against the eigenvalues it is defined by,
1 vs 2 ranks, and the command line."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.contact.friction import Friction
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.analysis.coulomb_bound import compliance, coulomb_bound, mu_critical
from sdm_dolfinx.problems import block

COMM = MPI.COMM_WORLD


def _dense_compliance(problem, dt):
    """(G_nn, G_nt) from the dense inverse of K (serial)."""
    d = Discretisation(problem, "P2/P1")
    integ = Integrator(d, "midpoint", dt, friction=Friction("coulomb", mu=0.0))
    n = integ.K.getSize()[0]
    K = integ.K.getValues(range(n), range(n))
    Kinv = np.linalg.inv(K)
    nd, td = integ.solver.ndofs, integ.solver.tdofs
    out = Kinv[np.ix_(nd, nd)], Kinv[np.ix_(nd, td)]
    mine = compliance(integ)
    integ.destroy()
    return out, mine


def test_compliance_is_the_inverse_at_the_contact_dofs():
    (Gnn, Gnt), (gnn, gnt) = _dense_compliance(block.problem(comm=MPI.COMM_SELF, nx=4, ny=2), 1e-4)
    scale = np.abs(Gnn).max()
    assert np.abs(Gnn - gnn).max() < 1e-10 * scale and np.abs(Gnt - gnt).max() < 1e-10 * scale


def test_bound_is_where_the_symmetric_part_stops_being_positive_definite():
    (Gnn, Gnt), _ = _dense_compliance(block.problem(comm=MPI.COMM_SELF, nx=4, ny=2), 1e-4)
    sigma = np.ones(len(Gnn))
    mu = mu_critical(Gnn, Gnt, sigma)
    assert np.isfinite(mu) and mu > 0

    def lowest(m):
        N = Gnn - m * Gnt * sigma[None, :]
        return np.linalg.eigvalsh(0.5 * (N + N.T)).min()
    assert lowest(0.99 * mu) > 0 > lowest(1.01 * mu)


@pytest.mark.mpi
def test_one_and_all_ranks_give_the_same_bound():
    a = coulomb_bound(block.problem(comm=MPI.COMM_SELF), "P2/P1", 1e-4)
    b = coulomb_bound(block.problem(), "P2/P1", 1e-4)
    assert a["vertices"] == b["vertices"] == 11
    assert abs(a["mu_c"] - b["mu_c"]) < 1e-9 * a["mu_c"]


@pytest.mark.skipif(COMM.size > 1, reason="the command line prints on rank 0 only: checked on 1 rank")
def test_command_line(capsys):
    from sdm_dolfinx.cli import main
    assert main(["inspect", "--problem", "block", "--pair", "P2/P1", "--coulomb-bound", "--dt", "1e-4"]) == 0
    out = capsys.readouterr().out
    assert "Coulomb step problem (all 11 constrained vertices in contact and slipping, dt = 0.0001, midpoint)" in out
    assert main(["inspect", "--problem", "membrane", "--coulomb-bound"]) == 2
    err = capsys.readouterr().err
    assert "scalar unknown" in err and err.count("\n") == 1 and "Traceback" not in err
