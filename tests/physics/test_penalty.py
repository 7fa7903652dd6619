"""The penalised contact (contact/penalty.py) through ``Integrator(contact="penalty")``.

The facts tested, each with its tolerance:

* the midpoint scheme's energy identity: kinetic + potential + E_pen changes at a step only by
  sum_i s_i k_i / 2 min(a_i^2, b_i^2) over the dofs whose penetration lb_i - U_i changes sign
  between U^n (a_i) and U^{n+1} (b_i), s_i = +1 entering, -1 leaving (E_pen is quadratic
  where no sign changes; the midpoint rule is exact for quadratic energies): to round-off, so
  the energy is conserved to round-off at every step without a contact change;
* that defect is O(dt^2): the largest energy deviation over the membrane's impact (dozens of
  vertices entering and leaving at different times) fitted on 3 dt's;
* the penetration at the constrained iterate X (where the springs act: X_c = lb - lam / k)
  falls like 1 / epsilon when the contact node has no inertia (the singular mass P1+/P0 of
  the rod: the force stays the contact stress), like epsilon^(-1/2) with the standard
  consistent mass (the node's kinetic energy m v^2 / 2 goes into the spring k delta^2 / 2);
* 1 and 2 ranks agree (the block dropped on the foundation).
"""
from mpi4py import MPI

import numpy as np
import pytest

from contact_runs import Run
from sdm_dolfinx import contact
from sdm_dolfinx.contact import penalty as _penalty
from sdm_dolfinx.problems import block, membrane, rod1d

COMM = MPI.COMM_WORLD
#: the energy identity holds to round-off, relative to the initial energy: measured 6e-14 (P1/P1),
#: 1.2e-13 (P2/P2) and 1.7e-12 (P1+/P0, whose Vbar grows to 3e3 on the dofs without mass, where it
#: carries no energy but the kinetic energy's round-off) over the rod's 600 steps
IDENTITY_RTOL = 1e-11


def crossing_defect(k, lb, a_state, b_state, cdofs):
    """sum_i s_i k_i / 2 min(a_i^2, b_i^2) over the local dofs whose penetration changes sign."""
    a, b = lb - a_state[cdofs], lb - b_state[cdofs]
    cross = a * b < 0.0
    sign = np.where(b > 0.0, 1.0, -1.0)
    return float(np.sum(np.where(cross, sign * 0.5 * k * np.minimum(a * a, b * b), 0.0)))


@pytest.mark.parametrize("pair", ["P1/P1", "P2/P2", "P1+/P0"])
def test_midpoint_energy_identity(pair):
    """Rod, one contact phase: each step's energy change is the crossing defect, to round-off."""
    run = Run(rod1d.problem(NX=20), pair, 5e-3, "penalty").advance(3.0, keep=True)
    tr, d = run.treatment, run.d
    dE = np.diff(run.energy)
    pred = np.array([run.global_sum(crossing_defect(tr.k, tr.lb, a, b, d.cdofs))
                     for a, b in zip(run.states[:-1], run.states[1:])])
    assert np.max(np.abs(dE - pred)) <= IDENTITY_RTOL * run.energy[0]
    assert np.count_nonzero(pred > 0) >= 1 and np.count_nonzero(pred < 0) >= 1   # entered and left
    quiet = pred == 0.0
    assert np.count_nonzero(quiet) > 0.9 * len(dE)
    assert np.max(np.abs(dE[quiet])) <= IDENTITY_RTOL * run.energy[0]          # conserved there
    run.destroy()


def test_midpoint_energy_error_is_second_order():
    """Membrane N = 10, P1+/P0, its impact: max |E - E0| over the run ~ dt^2 (the fitted order
    in [1.8, 2.4]; measured 2.07, 2.09 on dt = 4e-3, 2e-3, 1e-3); before the first contact the
    energy is conserved to round-off."""
    dts, dev = (4e-3, 2e-3, 1e-3), []
    for dt in dts:
        run = Run(membrane.problem(N=10), "P1+/P0", dt, "penalty").advance(0.5)
        E = np.array(run.energy)
        dev.append(np.max(np.abs(E - E[0])))
        first = next(i for i, info in enumerate(run.infos) if info["gap_end"] < 0.0)   # U^{n+1} below
        assert np.max(np.abs(E[:first + 1] - E[0])) <= IDENTITY_RTOL * E[0]
        run.destroy()
    order = np.polyfit(np.log(dts), np.log(dev), 1)[0]
    assert 1.8 <= order <= 2.4, (order, dev)


def max_penetration(pair, penalty, dt=1e-3):
    """max over the steps of lb - X_c = lam / k at the rod's contact point (X the constrained iterate)."""
    run = Run(rod1d.problem(NX=20), pair, dt, "penalty", {"penalty": penalty}).advance(2.5)
    k = run.treatment.k
    pen = max((float(np.max(lam / k)) if len(lam) else 0.0) for lam in run.lam)
    run.destroy()
    return COMM.allreduce(pen, op=MPI.MAX)


@pytest.mark.parametrize("pair,order", [("P1+/P0", -1.0), ("P1/P1", -0.5)])
def test_penetration_against_epsilon(pair, order):
    """Massless contact node (P1+/P0): penetration ~ 1/epsilon (fitted slope -0.994 on penalty
    4, 16, 64); standard mass (P1/P1): ~ epsilon^(-1/2) (fitted -0.58, successive -0.65, -0.52,
    -0.55 up to 256: the impact's kinetic energy)."""
    penalties = (4.0, 16.0, 64.0)
    pen = [max_penetration(pair, p) for p in penalties]
    slope = np.polyfit(np.log(penalties), np.log(pen), 1)[0]
    assert abs(slope - order) <= (0.02 if order == -1.0 else 0.15), (slope, pen)


def test_epsilon_is_the_rods_modulus_over_h():
    """The P1 rod: epsilon = penalty E / h (GetFEM's gamma0_P / h), k = epsilon at x = 0."""
    run = Run(rod1d.problem(NX=20), "P1/P1", 1e-3, "penalty", {"penalty": 3.0})
    assert run.treatment.epsilon == pytest.approx(3.0 * 20.0, rel=1e-12)
    run.destroy()


def test_options_refused_in_one_line():
    assert contact.check("penalty", {"penalty": -1.0}) == ["penalty must be a finite number > 0 (got -1.0)"]
    assert contact.check("penalty", {"nitsche_theta": 1}) == [
        "contact penalty has no parameter nitsche_theta (it takes penalty)"]
    assert "unknown contact treatment" in contact.check("springs")[0]
    assert contact.check("penalty", {"penalty": None, "nitsche_theta": None}) == []
    assert _penalty.DEFAULT_PENALTY == 1.0


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank run with a serial one: needs mpirun -n 2")
def test_one_and_two_ranks_agree():
    """The block dropped on the foundation (P2/P1, 100 steps): the kinetic, potential and
    penalty energies and the contact force on 2 ranks equal a serial run to 1e-10 relative."""
    par = ranks_series(COMM, "penalty")
    ser = COMM.bcast(ranks_series(MPI.COMM_SELF, "penalty") if COMM.rank == 0 else None, root=0)
    for p, s in zip(par.T, ser.T):
        assert np.max(np.abs(p - s)) <= 1e-10 * np.max(np.abs(s))


def ranks_series(comm, name, options=None):
    """(kinetic, potential, contact energy, contact force) after each of 100 steps of the block
    dropped on the foundation (P2/P1, dt = 1e-4 s) on ``comm``."""
    run = Run(block.problem(comm=comm, start="rest", v0=0.0), "P2/P1", 1e-4, name, options).advance(0.01)
    force = [run.d.comm.allreduce(float(np.sum(lam)), op=MPI.SUM) for lam in run.lam]
    out = np.column_stack([np.array(run.parts[1:]), force])
    run.destroy()
    return out
