"""The new time schemes on 2 ranks against the same run on one (under mpirun -n 2): the
membrane through its impact with Newmark (stateful: the acceleration), HHT, central
differences (CFL bound measured with SLEPc, mass factorised by MUMPS or redundantly) and
Taylor-Flanagan (bounds changed every step)."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.problems import membrane

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi


def history(comm, scheme, mass, dt, steps, options):
    """Energy, summed contact force and active count per step; the CFL bound (collective on comm)."""
    d = Discretisation(membrane.problem(comm, N=8), "P1/P1", mass)
    integ = Integrator(d, scheme, dt=dt, scheme_options=options)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    out = []
    for n in range(steps):
        info = integ.step(U, V, n, n * dt)
        out.append([sum(integ.energies(U, V)), comm.allreduce(float(np.sum(integ.lam)), op=MPI.SUM),
                    info["n_active"], info["gap_imposed"]])
    cfl = getattr(integ, "cfl", {}).get("dt_max", 0.0)
    integ.destroy()
    return np.array(out), cfl


@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank run with a serial one: needs mpirun -n 2")
@pytest.mark.parametrize("scheme,mass,dt,options", [("newmark", "row-sum", 2e-3, None),
                                                    ("hht", "row-sum", 2e-3, {"hht_alpha": -0.2}),
                                                    ("central-difference", "standard", 2e-3, None),
                                                    ("taylor-flanagan", "row-sum", 2e-3, None)])
def test_one_and_two_ranks_agree(scheme, mass, dt, options):
    """Through the impact (t = 0.6, the membrane touches at ~0.25): energies and contact forces
    equal the serial run's to 1e-10 relative, the active counts exactly, the CFL bound to 1e-9.
    (Not Newmark with the consistent mass: its chattering contact amplifies the ranks' round-off
    to 3e-9, as the midpoint scheme's with that mass, 6e-9, measured.)"""
    par, cfl = history(COMM, scheme, mass, dt, 300, options)
    ser = history(MPI.COMM_SELF, scheme, mass, dt, 300, options) if COMM.rank == 0 else None
    ser, cfl_ser = COMM.bcast(ser, root=0)
    assert ser[:, 2].max() > 0                          # it went through contact
    for j in (0, 1):
        assert np.abs(par[:, j] - ser[:, j]).max() <= 1e-10 * np.abs(ser[:, j]).max()
    assert np.array_equal(par[:, 2], ser[:, 2])
    assert cfl == pytest.approx(cfl_ser, rel=1e-9, abs=0.0)
