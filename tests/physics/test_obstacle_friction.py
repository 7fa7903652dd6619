"""Friction against rigid obstacles (``Problem.obstacles`` with ``friction``): Coulomb and Tresca in the
obstacle's frame at every node, 2-D and 3-D.

The frictional step solver works on a node's components in an orthonormal frame (its normal n_i and
tangents) given anew every step (:mod:`sdm_dolfinx.solvers.friction_system`, "Frames"); the
axis-aligned bound is the frame of e_c. The check is rotation invariance, as for the frictionless rows
(test_obstacle_contact.py): a body on an inclined plane under vertical gravity, meshed rotated by R,
against the same body axis-aligned on the unit rows' plane under gravity R^T g. The discrete problems
are the same up to R node-wise (A_rot = R A R^T, M likewise, L_rot = R L; the normal row n . u_i =
e_n . R^T u_i, the tangential conditions likewise, and Coulomb's and Tresca's laws are isotropic in the
tangent plane), so both runs take the same active, stick and slip sets and their energies, dissipated
energies and contact forces agree, and the friction force is rotated, up to the step solver's
tolerance (1e-10 of max|b|) and round-off:

* 2-D, the block of test_obstacle_contact.py on a 25-degree slope: sliding (Coulomb mu = 0.3 < tan 25 =
  0.47), sticking (mu = 0.6), Tresca; P1+/P0 at the vertices and P2/P1 at every node. Asserted 1e-9 of
  each column's scale (measured at most 2e-11).
* 3-D, a box on a plane tilted by 20 degrees about the horizontal diagonal (x = y): the normal has
  three non-zero components, so the tangents are not axes. Sliding (mu = 0.3) and sticking (0.8, 12 of
  16 vertices stick at the end, 4 slip). Asserted 1e-8 (measured at most 1e-9: the 3-D Newton's
  linearised cone converges to the tolerance, not to round-off); the friction force's Cartesian
  components (``tangential_force_x``, ``_y``, ``_z`` against obstacles) R f_0 within 1e-8 of |f_0|.
* Coulomb's law holds on a curved obstacle: the disc of demos/bowl_problem.py in the bowl (mu = 0.5,
  every node's frame its own): |sum lam_T| <= mu sum lam_N at every step (the 2-D force is signed along
  each node's tangent (n_y, -n_x)), the dissipated energy never decreases, and vertices stick (it
  rolls). Its period is not the rolling disc's 2 pi sqrt(3 L / (2 g)): the linear model's rotation field
  u = w x r is strain-free but moves the boundary to the radius r sqrt(1 + w^2), a spurious lift
  m g r w^2 / 2 of the same order as the pendulum's m g L theta^2 / 2 (w = L theta / r rolling); see
  docs/contact.md. That closed form waits for finite strain.
* Against a moving obstacle the slip is measured against the obstacle's surface (its material points
  carried over the step): a block at rest on a conveyor belt is dragged at mu g until it rides the belt,
  and seen from the belt it is the block sliding on a fixed floor (Galilean invariance). The weighted gap
  against obstacles is refused in one line. (A constrained node never has a Dirichlet
  component: ``dirichlet_facets`` fix every component and drop the node from the constraint, Dirichlet
  parts at constrained nodes are refused: so friction's frames always see free nodes.)
"""
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh as dmesh

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.obstacles import HalfSpace
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.run import simulate

from test_obstacle_contact import G, H, RHO, W, _block_on_slope, _elastic_body, _scale_diff

COMM = MPI.COMM_WORLD
DEMOS = Path(__file__).resolve().parents[2] / "demos"
COLUMNS = ("energy", "kinetic", "contact_force", "n_active", "dissipated", "n_stick", "n_slip")


@pytest.mark.parametrize("law,value,state", [("coulomb", 0.3, "slides"), ("coulomb", 0.6, "sticks"),
                                             ("tresca", 0.02, "slides")])
@pytest.mark.parametrize("pair,constrain", [("P1+/P0", "vertices"), ("P2/P1", "nodes")])
def test_friction_on_an_inclined_plane_is_friction_under_tilted_gravity(law, value, state, pair, constrain):
    option = {"mu": value} if law == "coulomb" else {"tresca_threshold": value}
    kw = dict(pair=pair, constrain=constrain, dt=2e-5, T=4e-3, friction=law, friction_options=option)
    p0, R = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, **kw).timeseries
    assert max(s0["contact_force"]) > 0
    assert s0["n_slip"][-1] + s0["n_stick"][-1] > 0 and (s0["n_stick"][-1] > 0) == (state == "sticks")
    for c in COLUMNS + ("tangential_force",):
        assert _scale_diff(s0[c], s1[c]) <= 1e-9, c
    p0v = np.vstack([s0["momentum_x"], s0["momentum_y"]])
    p1v = np.vstack([s1["momentum_x"], s1["momentum_y"]])
    assert np.max(np.abs(R @ p0v - p1v)) <= 1e-9 * np.max(np.abs(p0v))


def _axis_rotation(theta):
    """The rotation by ``theta`` degrees about the horizontal diagonal (1, 1, 0) / sqrt 2 (Rodrigues)."""
    a = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    th = np.radians(theta)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(th) * k + (1.0 - np.cos(th)) * k @ k


def _box_on_slope(theta, rotated, L=10.0, H=5.0, E=1000.0, nu=0.3, rho=1e-6, g=9810.0):
    """A box L x L x H (3 x 3 x 1 cells) on the plane with normal R e_z under vertical gravity, its mesh
    rotated by R (``rotated``), or axis-aligned on z >= 0 under gravity R^T (0, 0, -g)."""
    msh = dmesh.create_box(COMM, [np.zeros(3), np.array([L, L, H])], [3, 3, 1], dmesh.CellType.tetrahedron)
    R = _axis_rotation(theta)
    nrm = R[:, 2]
    if rotated:
        msh.geometry.x[:, :] = msh.geometry.x @ R.T
        grav = np.array([0.0, 0.0, -g])
        bottom = lambda x: np.isclose(nrm @ x, 0.0, atol=1e-9)                 # noqa: E731
        contact = dict(lower_bound=None, obstacles=[HalfSpace((0.0, 0.0, 0.0), nrm)])
    else:
        grav = R.T @ np.array([0.0, 0.0, -g])
        bottom = lambda x: np.isclose(x[2], 0.0)                              # noqa: E731
        contact = dict(lower_bound=lambda x: -x[2])
    p = _elastic_body(msh, grav, bottom, contact, ("contact_force",), E=E, nu=nu, rho=rho)
    return p, R


@pytest.mark.parametrize("mu,state", [(0.3, "slides"), (0.8, "sticks")])
def test_3d_friction_on_a_tilted_plane_is_friction_under_tilted_gravity(mu, state):
    kw = dict(pair="P1+/P0", dt=2e-5, T=2e-3, friction="coulomb", friction_options={"mu": mu})
    p0, R = _box_on_slope(20.0, False)
    p1, _ = _box_on_slope(20.0, True)
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, **kw).timeseries
    assert s0["n_slip"][-1] + s0["n_stick"][-1] > 0 and (s0["n_stick"][-1] > 0) == (state == "sticks")
    for c in COLUMNS:
        assert _scale_diff(s0[c], s1[c]) <= 1e-8, c
    f0 = np.vstack([s0["tangential_force_x"], s0["tangential_force_y"], np.zeros(len(s0["t"]))])
    f1 = np.vstack([s1["tangential_force_x"], s1["tangential_force_y"], s1["tangential_force_z"]])
    assert np.max(np.abs(R @ f0 - f1)) <= 1e-8 * np.max(np.abs(f0))


def test_a_disc_rolling_in_a_bowl_keeps_coulombs_law():
    spec = load_file(DEMOS / "bowl_problem.py")
    T0 = spec.problem(COMM).parameters["period"]
    kw = dict(pair="P1+/P0", dt=T0 / 1000, T=0.25 * T0)
    rolling = simulate(spec.problem(COMM, h=2.0), friction="coulomb", friction_options={"mu": 0.5}, **kw)
    ts = rolling.timeseries
    force, normal = np.abs(np.asarray(ts["tangential_force"])), np.asarray(ts["contact_force"])
    assert np.all(force <= 0.5 * normal * (1 + 1e-8) + 1e-12) and force.max() > 0
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * max(ts["kinetic"]))
    assert np.max(ts["n_stick"]) > 0


def _belt(V, v0, pair, mu=0.3, T=0.05):
    """The block (W x H, nu = 0, 8 x 4 cells) at its equilibrium on the floor y = 0 (a half-space), moving
    at v0; the floor a belt moving along x at V (V = 0: fixed); Coulomb mu; the time series."""
    msh = dmesh.create_rectangle(COMM, [np.zeros(2), np.array([W, H])], [8, 4], dmesh.CellType.triangle)
    motion = dict(motion=lambda t: (V * t, 0.0, 0.0), motion_velocity=lambda t: (V, 0.0, 0.0)) if V else {}
    belt = HalfSpace((0.0, 0.0), (0.0, 1.0), **motion)
    p = _elastic_body(msh, np.array([0.0, -G]), lambda x: np.isclose(x[1], 0.0),
                      dict(lower_bound=None, obstacles=[belt]), ("contact_force", "momentum_x", "momentum_y"), nu=0.0)
    p.u0 = "equilibrium"
    p.v0 = lambda x: np.vstack([np.full(x.shape[1], v0), 0.0 * x[0]])
    return simulate(p, pair=pair, dt=1e-4, T=T, friction="coulomb", friction_options={"mu": mu}).timeseries


@pytest.mark.parametrize("pair", ["P1+/P0", "P2/P1"])
def test_a_block_on_a_conveyor_belt_is_dragged_at_mu_g_then_rides_it(pair):
    """The block at rest on a belt moving at V = 100 mm/s: the slip (measured against the belt's surface)
    is backwards, so friction drags the block forwards at mu g until its speed is V, at t* = V / (mu g)
    = 34 ms; then it sticks and rides the belt. Asserted: the acceleration (the fit of momentum_x / m
    before 0.9 t*) mu g within 2e-4 (measured -2.0e-5 with P1+/P0), the speed within 1 % of V from 1.2 t*
    on, the dissipated energy never decreasing, and obstacle_work (the belt's work through friction) V
    times the block's momentum at every step within 1e-8 of m V^2 (measured 1.8e-10). Measured in the
    fixed frame the slip would be forwards and friction would brake a block that does not move."""
    V, mu = 100.0, 0.3
    ts = _belt(V, 0.0, pair)
    m = RHO * W * H
    t, v = ts["t"], ts["momentum_x"] / m
    t_star = V / (mu * G)
    before = (t > 0.0) & (t < 0.9 * t_star)
    a = np.polyfit(t[before], v[before], 1)[0]
    assert abs(a / (mu * G) - 1.0) < 2e-4, a / (mu * G) - 1.0
    assert np.max(np.abs(v[t >= 1.2 * t_star] / V - 1.0)) < 0.01
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * np.max(ts["kinetic"]))
    # the belt's work: friction is the only horizontal force and the belt moves at V, so its work is V
    # times the impulse it gave, V momentum_x, at every step (m V^2 in the end: half kinetic, half dissipated)
    assert np.max(np.abs(ts["obstacle_work"] - V * ts["momentum_x"])) <= 1e-8 * m * V ** 2


def test_a_box_on_a_belt_moving_along_a_diagonal_is_dragged_along_it():
    """3-D (the frictional cone in each node's frame): a box 10 x 10 x 5 mm (2 x 2 x 1 cells, P2/P1, nu = 0)
    at rest on the plane z = 0 moving at V = 100 mm/s along 30 degrees: dragged at mu g along the belt's
    direction (asserted 2e-4; measured -7.9e-6), its velocity across it below 0.5 % of V (measured 0.16 %:
    the unstructured tetrahedra's normal forces are not symmetric about the direction), riding the belt
    within 1 % from 1.2 t* on (measured 0.35 %)."""
    V, mu = 100.0, 0.3
    e = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0])
    msh = dmesh.create_box(COMM, [np.zeros(3), np.array([10.0, 10.0, 5.0])], [2, 2, 1], dmesh.CellType.tetrahedron)
    belt = HalfSpace((0, 0, 0), (0, 0, 1), motion=lambda t: tuple(V * t * e), motion_velocity=lambda t: tuple(V * e))
    p = _elastic_body(msh, np.array([0.0, 0.0, -G]), lambda x: np.isclose(x[2], 0.0),
                      dict(lower_bound=None, obstacles=[belt]), ("contact_force", "momentum_x", "momentum_y"), nu=0.0)
    p.u0 = "equilibrium"
    ts = simulate(p, pair="P2/P1", dt=1e-4, T=0.05, friction="coulomb", friction_options={"mu": mu}).timeseries
    m = RHO * 10.0 * 10.0 * 5.0
    t, vx, vy = ts["t"], ts["momentum_x"] / m, ts["momentum_y"] / m
    along, across = vx * e[0] + vy * e[1], -vx * e[1] + vy * e[0]
    t_star = V / (mu * G)
    before = (t > 0.0) & (t < 0.9 * t_star)
    a = np.polyfit(t[before], along[before], 1)[0]
    assert abs(a / (mu * G) - 1.0) < 2e-4, a / (mu * G) - 1.0
    assert np.max(np.abs(across)) < 5e-3 * V
    assert np.max(np.abs(along[t >= 1.2 * t_star] / V - 1.0)) < 0.01


def test_the_belt_seen_from_the_belt_is_the_block_sliding_on_a_fixed_floor():
    """Galilean invariance: the block at rest on the belt moving at V is, in the belt's frame, the block
    sliding at -V on a fixed floor. The discrete problems are the same up to the translation V t of every
    node (the rows do not see a tangential motion of a plane; the slip's reference is carried by the belt's
    motion), so momentum_x differs by m V and the contact force, the friction force, the sets and the
    dissipated energy (friction's work on the relative slip) are the same, up to the frictional Newton's
    tolerance 1e-10 max|b|: |b| ~ alpha^2 M U grows with the belt run's translation U_x <= 5 mm to ~1e4
    N, so 1e-6 N per node against m g = 2 N, and over 500 steps of 1e-4 s on 9 nodes an impulse of up to
    4.5e-9 against m V = 0.02 (asserted 1e-5 relative for forces, 1e-6 for momentum and dissipation;
    measured 1.1e-6, 1.7e-8, 2.5e-9 on 1 rank; 1.5e-7 for momentum on 2 ranks with dolfinx 0.9)."""
    V = 100.0
    belt, fixed = _belt(V, 0.0, "P1+/P0"), _belt(0.0, -V, "P1+/P0")
    m = RHO * W * H
    assert np.max(np.abs(belt["momentum_x"] - (fixed["momentum_x"] + m * V))) <= 1e-6 * m * V
    for c in ("contact_force", "tangential_force"):
        assert np.max(np.abs(belt[c] - fixed[c])) <= 1e-5 * np.max(np.abs(fixed[c])), c
    assert np.max(np.abs(belt["dissipated"] - fixed["dissipated"])) <= 1e-6 * np.max(fixed["dissipated"])
    assert np.array_equal(belt["n_slip"], fixed["n_slip"]) and np.array_equal(belt["n_active"], fixed["n_active"])


def test_friction_on_the_weighted_gap_is_refused_against_obstacles():
    p, _ = _block_on_slope(0.0, True, n=4)
    with pytest.raises(SdmError, match="constrain='weighted' against obstacles"):
        simulate(p, pair="P2/P1", dt=1e-4, T=1e-3, constrain="weighted", friction="coulomb",
                 friction_options={"mu": 0.3})


def test_the_coulomb_bound_is_not_measured_against_obstacles():
    """inspect --coulomb-bound measures K^-1 on the axis-aligned normal and tangential dofs: against an
    obstacle (each node's normal its own) that would be another matrix, so it refuses in one line."""
    from sdm_dolfinx.analysis.coulomb_bound import coulomb_bound
    with pytest.raises(SdmError, match="coulomb-bound is derived for the axis-aligned bound"):
        coulomb_bound(_block_on_slope(10.0, True, n=4)[0], "P1+/P0", 1e-4)


def test_3d_friction_fields_against_an_obstacle_are_cartesian_and_tangential(mpi_tmp_path):
    """The XDMF's tangential_stress of a 3-D run against a tilted plane is the Cartesian vector of the
    friction stress: orthogonal to the plane's normal (to round-off: measured 1e-18 of 0.025) and not zero
    (it crashed before the first step's frames when written at step 0)."""
    import h5py
    p, R = _box_on_slope(20.0, True)
    out = mpi_tmp_path / "box"
    simulate(p, pair="P1+/P0", dt=2e-5, T=4e-4, friction="coulomb", friction_options={"mu": 0.3}, out=out,
             write_every=5)
    if COMM.rank == 0:
        with h5py.File(out / "solution.h5", "r") as f:
            group = f["Function/tangential_stress"]
            last = group[sorted(group, key=lambda k: float(k.replace("_", ".")))[-1]][:]
        assert np.abs(last).max() > 0
        assert np.abs(last @ R[:, 2]).max() <= 1e-12 * np.abs(last).max()
