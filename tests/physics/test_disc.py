"""The falling disc (paper section 5): mesh levels, free flight, momentum balance, energy, rebound."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import disc, simulate
from sdm_dolfinx.cli import main as cli_main
from sdm_dolfinx.problems import disc_mesh
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator

COMM = MPI.COMM_WORLD


R, HEIGHT, V0, G = 20.0, 10.0, -1000.0, 9810.0       # the defaults (mm, mm, mm/s, mm/s^2)


MASS = 1e-6 * np.pi * R ** 2                         # rho |disc| (t per mm of thickness)


#: the semi-smooth Newton accepts an inactive vertex within rtol = 1e-10 of the right-hand
#: side's scale, i.e. ~1e-10 x the coordinates (<= 30 mm): 1e-9 x 30 mm leaves a factor 10
GAP_TOL = 1e-9 * (R + HEIGHT)


#: relative tolerance of every linear solve of a step (solvers.active_set.InactiveSetSolver's ksp rtol)
KSP_RTOL = 1e-12


_RUNS = {}


def run(pair="P2/P1", dt=1e-4, T=0.02, scheme="midpoint", **problem_args):
    """A level-1 run, cached: only the time series and scalars are kept (no PETSc objects)."""
    key = (pair, dt, T, scheme, tuple(sorted(problem_args.items())))
    if key not in _RUNS:
        r = simulate(disc.problem(level=1, **problem_args), pair=pair, scheme=scheme, dt=dt, T=T)
        _RUNS[key] = {"ts": r.timeseries, "info": r.info, "gap_imposed": r.gap_imposed.copy()}
    return _RUNS[key]


def rel_energy_error(E):
    """max_n |E^n - E^0| / E^0 over the whole run."""
    return float(np.max(np.abs(E - E[0])) / abs(E[0]))


def test_mesh_levels_and_curved_boundary():
    """The levels have about the paper's dof counts (Table 2: 622, 2782) and P2 geometry.

    A straight-sided disc with level 1's 28 boundary edges would miss
    1 - sin(2 pi/28) / (2 pi/28) = 0.8 % of the area; quadratic edges miss O(h^4): we ask
    for the mass within 1e-4.
    """
    # gmsh versions mesh differently: Debian 12's gmsh 4.8 gives 618, 2786, 11130, 45458 dofs
    # (-0.6 %, +0.1 %, -1.6 %, -0.5 %), Debian 13's 4.13 gives 658 and 2730 for levels 1-2
    # (dolfinx 0.9 chroot): within 8 % of the paper either way (levels 5-6, 126k and 513k
    # dofs, take 9 s and a minute to mesh: counted in bench/ and in the report's Table 2)
    for level, tol in ((1, 0.08), (2, 0.08), (3, 0.08), (4, 0.08)):
        msh, _ = disc_mesh.make_mesh(disc_mesh.LEVELS[level], centre=(0.0, R + HEIGHT))
        n = disc_mesh.p2_dofs(msh)
        assert abs(n - disc_mesh.PAPER_DOFS[level]) <= tol * disc_mesh.PAPER_DOFS[level], (level, n)
    p = disc.problem(level=1)
    assert abs(disc.total_mass(p) - MASS) < 1e-4 * MASS
    d = Discretisation(p, "P2/P1")
    # the contact vertices are the boundary vertices of the lower half, A among them
    y = COMM.allgather(d.cx[1])
    y = np.concatenate(y)
    assert y.max() <= R + HEIGHT + 1e-12 and np.isclose(y.min(), HEIGHT, rtol=0, atol=1e-12)
    assert d.num_constraints == len(y) >= 10


@pytest.mark.parametrize("pair", ["P2/P1", "P2/P2"])
def test_free_flight(pair):
    """Before contact the discrete solution is the exact free fall.

    For a uniform gravity load l(w) = rho g.w, M e_y = (rho phi_j . e_y) is the load per
    unit g for both the singular and the standard mass, so the rigid motion
    U^n = (V0 t - g t^2/2) e_y solves the midpoint scheme exactly (A e_y = 0, and the
    midpoint rule is exact for constant acceleration). Hence: U is that translation, the
    momentum is m (V0 - g t), and the energy (kinetic + elastic + gravity) is constant. What
    remains is round-off (the linear solves converge to it: one CG iteration preconditioned
    by the factorised step matrix) over 50 steps, where the energy sums terms of ~600 N mm
    that cancel: we ask 1e-11 relative (~5e4 eps) for the energy, 1e-10 for the motion.
    """
    dt, T = 1e-4, 0.005
    p = disc.problem(level=1, with_contact=False)
    r = simulate(p, pair=pair, dt=dt, T=T)
    ts = r.timeseries
    E = ts["energy"]
    assert rel_energy_error(E) < 1e-11
    t = ts["t"]
    m = disc.total_mass(p)
    np.testing.assert_allclose(ts["momentum_y"], m * (V0 - G * t), rtol=0, atol=1e-10 * m * abs(V0))
    d = V0 * T - 0.5 * G * T ** 2                         # displacement of the free fall (mm)
    u = r.U.array.reshape(-1, 2)
    err = COMM.allreduce(float(np.max(np.abs(u - [0.0, d]), initial=0.0)), op=MPI.MAX)
    assert err < 1e-10 * abs(d)
    # the rigid motion carries no elastic energy (1/2 U^T A U of a translation: round-off,
    # measured 6e-11 N mm against 628): potential = gravity only = m g d
    assert np.max(np.abs(ts["elastic"])) < 1e-11 * E[0]
    np.testing.assert_allclose(ts["potential"][-1], m * G * d, rtol=1e-10)


def test_without_gravity_the_disc_moves_uniformly():
    """gravity = 0 (a valid input: the load form is then zero): before contact every point
    moves at V0, so the momentum m V0 and the energy m V0^2 / 2 stay constant (round-off:
    1e-11 relative, as in free flight) and U = V0 t exactly."""
    dt, T = 1e-4, 0.005
    p = disc.problem(level=1, with_contact=False, gravity=0.0)
    r = simulate(p, pair="P2/P1", dt=dt, T=T)
    ts, m = r.timeseries, disc.total_mass(p)
    np.testing.assert_allclose(ts["energy"], 0.5 * m * V0 ** 2, rtol=1e-11)
    np.testing.assert_allclose(ts["momentum_y"], m * V0, rtol=1e-11)
    u = r.U.array.reshape(-1, 2)
    err = COMM.allreduce(float(np.max(np.abs(u - [0.0, V0 * T]), initial=0.0)), op=MPI.MAX)
    assert err < 1e-10 * abs(V0 * T)


@pytest.mark.parametrize("pair,scheme", [("P2/P1", "midpoint"), ("P2/P2", "midpoint"),
                                         ("P2/P1", "backward-euler")])
def test_impulse_momentum_balance(pair, scheme):
    """dt sum_n F^{n+1} = p^N - p^0 + m g T with p = e_y^T M Vbar, F the sum of the multipliers.

    Multiplying a step's equation K X - b = lam by e_y^T (A e_y = 0, e_y^T L = -m g) gives
    exactly (p^{n+1} - p^n)/dt + m g = e_y^T lam for the midpoint scheme and for backward
    Euler. Each step leaves the linear solver's residual (relative 1e-12 of the right-hand
    side); summed over N steps we allow N x 1e-12 of the impulse scale m (|V0| + g T).
    """
    dt, T = 1e-4, 0.02
    ts = run(pair, dt, T, scheme)["ts"]
    assert ts["n_active"].max() >= 1                      # there was an impact
    n = len(ts["t"]) - 1
    impulse = dt * np.sum(ts["contact_force"][1:])
    m = disc.total_mass(disc.problem(level=1))           # e^T M e: the mesh's mass, not rho pi R^2
    residual = impulse - (ts["momentum_y"][-1] - ts["momentum_y"][0]) - m * G * n * dt
    assert abs(residual) < n * KSP_RTOL * m * (abs(V0) + G * T), residual


def test_p2p1_midpoint_no_penetration_and_energy_converges():
    """P2/P1, midpoint (paper Fig. 15): U^{n+1/2} never penetrates; the energy error shrinks with dt.

    The constraint holds on U^{n+1/2} up to GAP_TOL. Both the largest relative energy
    deviation over the run and the final one (the paper's Fig. 11 measure) must decrease
    along dt = 1e-4, 2.5e-5, 1e-5, be below 5 % at 1e-4 and below 1 % at 1e-5 (in the
    paper's Fig. 15 the dt = 1e-5 energy is flat to the eye).
    """
    dts = (1e-4, 2.5e-5, 1e-5)
    largest, final = [], []
    for dt in dts:
        r = run("P2/P1", dt, 0.02)
        ts = r["ts"]
        assert ts["n_active"].max() >= 1
        assert r["gap_imposed"].min() >= -GAP_TOL, (dt, r["gap_imposed"].min())
        assert r["info"]["constraint_imposed_on"] == "U^{n+1/2}"
        E = ts["energy"]
        largest.append(rel_energy_error(E))
        final.append(abs(E[-1] - E[0]) / E[0])
    assert largest[0] < 0.05 and largest[-1] < 0.01, largest
    assert np.all(np.diff(largest) < 0), largest
    assert np.all(np.diff(final) < 0), final


def test_p2p2_standard_mass_blows_up_at_impact():
    """P2/P2 with the standard mass, midpoint, dt = 1e-5 (paper Fig. 14): the energy blows up.

    The paper's run put contact on every boundary node; ours constrains the vertices only
    and is unstable as well: within 2 ms of the impact the energy has more than doubled,
    while P2/P1 at the same dt stays within 1 % (previous test).
    """
    dt, T = 1e-5, 0.0115
    ts = run("P2/P2", dt, T)["ts"]
    E = ts["energy"]
    t_impact = ts["t"][np.argmax(ts["n_active"] > 0)]
    assert 0.009 < t_impact < 0.0100                    # free fall: A reaches y = 0 at t = 9.55 ms
    assert E[-1] > 2.0 * E[0], E[-1] / E[0]
    ref = run("P2/P1", dt, 0.02)["ts"]["energy"]
    assert rel_energy_error(ref) < 0.01


def test_elastic_energy_at_maximal_compression():
    """P2/P1, midpoint, dt = 1e-4: the elastic energy 1/2 U^T A U is never negative (A is
    positive semi-definite; round-off of a 10 mm translation: 1e-11 of E^0), zero before
    the impact, and at its largest (maximal compression) it holds nearly all the energy:
    the disc is almost at rest there (kinetic energy < 5 % of E^0; measured 1.4 %), the
    elastic energy exceeding E^0 by the work of gravity over the fall."""
    ts = run("P2/P1", 1e-4, 0.02)["ts"]
    E0, el = ts["energy"][0], ts["elastic"]
    assert el.min() >= -1e-11 * E0
    before = ts["n_active"].cumsum() == 0
    assert np.max(np.abs(el[before])) < 1e-11 * E0
    k = int(np.argmax(el))
    assert ts["n_active"][k] > 0 and ts["kinetic"][k] < 0.05 * E0
    assert el[k] > E0


def test_rebound_is_physical():
    """P2/P1, midpoint, dt = 1e-4: every nodal multiplier is compressive (lam >= 0, up to the
    solver's tolerance), only the lower half touches, the disc's centre of mass stops
    falling, rises once contact ends with a speed no larger than the impact speed, and
    then decelerates at g again.
    """
    dt, T = 1e-4, 0.02
    p = disc.problem(level=1)
    d = Discretisation(p, "P2/P1")
    integ = Integrator(d, "midpoint", dt)
    U, V = d.initial_state()
    m = disc.total_mass(p)
    n = int(round(T / dt))
    ybar = np.zeros(n + 1)          # centre-of-mass displacement e^T M U / m
    mom = np.zeros(n + 1)
    force = np.zeros(n + 1)
    lam_min = np.inf
    touched_y = -np.inf
    mom[0] = integ.momentum(V, 1)
    for k in range(n):
        integ.step(U, V, k, k * dt)
        lam = integ.lam
        lam_min = min(lam_min, float(np.min(lam, initial=np.inf)))
        if np.any(lam > 0):
            touched_y = max(touched_y, float(np.max(d.cx[1][lam > 0])))
        force[k + 1] = COMM.allreduce(float(np.sum(lam)), op=MPI.SUM)
        ybar[k + 1] = integ.momentum(U, 1) / m
        mom[k + 1] = integ.momentum(V, 1)
    integ.destroy()
    lam_min = COMM.allreduce(lam_min, op=MPI.MIN)
    touched_y = COMM.allreduce(touched_y, op=MPI.MAX)
    in_contact = np.flatnonzero(force > 0)
    first, last = in_contact[0], in_contact[-1]
    # compressive only: the solver accepts lam >= -1e-10 x (right-hand side scale)
    assert lam_min >= -1e-9 * force.max()
    assert touched_y < R + HEIGHT                      # only the lower half touched
    # the centre falls until the impact and rises after contact ends
    assert np.all(np.diff(ybar[:first]) < 0)
    assert np.all(np.diff(ybar[last + 1:]) > 0) and last + 10 < n
    v_impact = -mom[first - 1] / m
    v_rebound = mom[last + 1] / m
    # some energy stays in vibrations: 0 < v_rebound <= v_impact (+ the 2 % energy error
    # this dt makes, see the previous test)
    assert 0.5 * v_impact < v_rebound <= 1.02 * v_impact, (v_impact, v_rebound)
    # after contact: free flight, dp/dt = -m g exactly (see test_impulse_momentum_balance)
    np.testing.assert_allclose(np.diff(mom[last + 1:]) / dt, -m * G, rtol=1e-8)
    # contact stress at A compressive in the recorded series too
    ts = run("P2/P1", dt, T)["ts"]
    assert ts["lambda_probe"].min() >= 0.0 and ts["lambda_probe"].max() > 0.0
    assert ts["contact_force"].min() >= -1e-9 * ts["contact_force"].max()


def test_mesh_file_gives_the_same_run(mpi_tmp_path, capsys):
    """``disc --mesh FILE.msh``: the level-1 mesh written to a file and read back gives the
    run of the generated mesh (same nodes, written with 16 digits: 1e-9 relative, through
    the impact); a missing, unreadable or mismatched file is bad input (status 2, one line)."""
    path = mpi_tmp_path / "disc.msh"
    if COMM.rank == 0:
        disc_mesh.write_msh(path, disc_mesh.LEVELS[1], radius=R, centre=(0.0, R + HEIGHT))
    COMM.Barrier()
    kw = dict(pair="P2/P1", dt=1e-4, T=0.012)
    a = simulate(disc.problem(mesh_file=path), **kw)
    b = run(**kw)
    assert a.info["problem"]["parameters"]["mesh_file"] == str(path)
    assert a.info["dim_W"] == b["info"]["dim_W"] and b["ts"]["n_active"].max() > 0
    np.testing.assert_array_equal(a.timeseries["n_active"], b["ts"]["n_active"])
    for c in ("energy", "u_probe", "lambda_probe", "contact_force", "momentum_y"):
        scale = np.max(np.abs(b["ts"][c]))
        np.testing.assert_allclose(a.timeseries[c], b["ts"][c], rtol=0, atol=1e-9 * scale, err_msg=c)
    junk = mpi_tmp_path / "junk.msh"
    if COMM.rank == 0:
        junk.write_text("$MeshFormat\nnot a mesh\n")
    COMM.Barrier()
    out = mpi_tmp_path / "never"
    capsys.readouterr()                 # the runs above may have warned (gap_min_boundary)
    for args, message in ((["--mesh", str(mpi_tmp_path / "missing.msh")], "no such file"),
                          (["--mesh", str(junk)], "junk.msh"),
                          (["--mesh", str(path), "--radius", "25"], "not the disc of radius 25"),
                          (["--mesh", str(path), "--h", "3"], "choose one")):
        assert cli_main(["disc", *args, "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        if COMM.rank == 0:
            assert message in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()

