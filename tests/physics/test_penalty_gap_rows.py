"""The penalty treatment on gap rows (``contact="penalty"`` with obstacles or ``--constrain weighted``):
springs lam_i = k_i (g_i - G_i X)_+ on the rows, solved by the gap-row Newton with the compliances 1/k
on its Schur complement's diagonal (sdm_dolfinx/contact/penalty.py).

* **Rotation invariance.** The block of test_obstacle_contact.py on a 25-degree inclined plane (mesh
  rotated, vertical gravity, a HalfSpace obstacle) against the axis-aligned block on the unit rows'
  penalty under gravity rotated by -25 degrees: the springs' stiffness epsilon = penalty x (mesh
  stiffness at the contact) is taken along each node's normal (n^T A_ii n, A_ii its diagonal block),
  which rotation leaves unchanged, so the discrete problems are the same up to the rotation: kinetic and
  contact energies and contact forces within 1e-9 of their scale (measured 3e-11), and the energy
  (kinetic + potential + contact_energy, conserved by the midpoint scheme to 1e-13 of the kinetic
  energy here) within 1e-9 of the largest kinetic energy. With epsilon from A_cc at the constrained
  component (the unit rows' rule) the rotated run differed by 11 % (measured): that rule is not
  rotation invariant.
* **Springs in series with the weighted gap** (demos/pushed_block_problem.py: the top pushed down by d
  = 10 um, nu = 0, the weighted rows' patch test of test_weighted_gap.py). The springs under the face
  carry the same force as the block, so the face sinks uniformly by delta and the block shortens by
  d - delta: the force is F (1 - delta / d) with F = E W d / H the exact contact's (asserted within 0.5 %
  for the punch's reaction and the foundation's force, with delta the face's sink at the end; measured
  2e-4), and the springs' law holds: delta = F' / (epsilon W) within 1 % (measured 4e-4 on P2/P1, 3e-3
  on P1+/P0; the rows are averages, so each one's force is epsilon m_i delta for a uniform sink). The penalty at its default (1) makes delta 14 % of d on P2/P1,
  7 % on P1+/P0 (measured): the penalty is compliant, the exact contact is not.
* A moving obstacle with the penalty is refused in one line (its stored energy would need the
  obstacle's time), as are the Nitsche treatment with gap rows (test_obstacle_contact.py,
  test_weighted_gap.py).
"""
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.contact.penalty import stiffness_scale
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.obstacles import HalfSpace
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.run import simulate

from test_obstacle_contact import _block_on_slope, _scale_diff

COMM = MPI.COMM_WORLD
PUSHED = Path(__file__).resolve().parents[2] / "demos" / "pushed_block_problem.py"
PUSH = 0.01


@pytest.mark.parametrize("pair,constrain", [("P1+/P0", "vertices"), ("P2/P1", "nodes")])
def test_penalty_on_an_inclined_plane_is_the_penalty_under_tilted_gravity(pair, constrain):
    kw = dict(pair=pair, constrain=constrain, dt=2e-5, T=4e-3, contact="penalty")
    p0, _ = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    r0, r1 = simulate(p0, **kw), simulate(p1, **kw)
    s0, s1 = r0.timeseries, r1.timeseries
    assert max(s0["contact_energy"]) > 0 and r1.info["min_gap_end"] < 0        # the springs work, it penetrates
    for c in ("kinetic", "contact_energy", "contact_force", "n_active"):
        assert _scale_diff(s0[c], s1[c]) <= 1e-9, c
    kin = max(s0["kinetic"])
    assert np.max(np.abs(np.asarray(s0["energy"]) - s1["energy"])) <= 1e-9 * kin
    assert abs(r0.info["min_gap_end"] - r1.info["min_gap_end"]) <= 1e-9 * abs(r0.info["min_gap_end"])


@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_penalty_springs_in_series_with_the_weighted_gap(pair):
    r = simulate(str(PUSHED), {"nu": 0.0}, pair=pair, constrain="weighted", contact="penalty")   # dt 1e-4, T 10 ms
    ts = r.timeseries
    p = load_file(PUSHED).problem(COMM, nu=0.0)
    F, W = p.parameters["force"], p.args["width"]
    hold = ts["t"] > 5e-3 * (1 + 1e-9)
    delta = -ts["gap_min_boundary"][-1]
    assert delta > 0.01 * PUSH                                              # the springs give way
    force = -ts["reaction_top_y"][hold].mean()
    assert force == pytest.approx(F * (1 - delta / PUSH), rel=5e-3)
    assert ts["contact_force"][hold].mean() == pytest.approx(force, rel=5e-3)
    epsilon = stiffness_scale(r.discretisation)                             # penalty 1 (the default)
    assert delta == pytest.approx(force / (epsilon * W), rel=1e-2)


def test_penalty_refuses_a_moving_obstacle():
    p, _ = _block_on_slope(0.0, True, n=4)
    p.obstacles = [HalfSpace((0.0, 0.0), (0.0, 1.0), motion=lambda t: (0.0, 0.1 * t))]
    with pytest.raises(SdmError, match="that move, which contact 'penalty'"):
        simulate(p, pair="P1+/P0", dt=1e-4, T=1e-3, contact="penalty")
