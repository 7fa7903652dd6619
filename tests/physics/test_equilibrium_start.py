"""The equilibrium start of any problem: ``u0 = "equilibrium"`` (sdm_dolfinx.method.equilibrium).

A body started at its static equilibrium U_s with zero velocity stays there: with U^n = U_s and
Vbar^n = 0 the midpoint step K X = b + lam (K = alpha^2 M + A, b = L + alpha^2 M U^n, alpha = 2/dt)
is solved by X = U_s with lam = A U_s - L, the static reactions, which satisfy the contact (and
friction) conditions; so U^n = U_s at every step, the velocity is zero and the foundation carries
the load's normal part at every step, up to the solves' round-off. Checked on

* the demos' problem file ``incline_problem.py`` at theta = 0 (a block on a flat foundation)
  against the built-in block's own equilibrium start (block.StaticStart, another solve): the same
  numbers to round-off, for the vertex and node constraint and two pairs;
* the same file at theta = 30 degrees with Coulomb friction mu = 0.8 > tan 30 (the block sticks),
  2-D and 3-D: no creep (the displacement changes by less than 1e-9 mm over the run, where the
  unstressed start rattles by more than 1e-4 mm), contact force m g cos theta, friction force
  m g sin theta;
* the membrane (a scalar problem with Dirichlet data): the static obstacle problem, at rest;
* a clamped block under a time-dependent load (the equilibrium under L(0)); Tresca friction;
* the refusals, one line each, where the static problem has no solution;
* ``u0`` as a dolfinx Function (interpolated into W^h);
* against obstacles (the static problem in each node's frame): an inclined plane against tilted
  gravity, and a disc at the bottom of a circular bowl;
* with the weighted gap (its rows held by multipliers): a bar under its own weight starts at the
  exact solution, 2-D and 3-D; the sticking block on the incline, 2-D and 3-D; the refusal.
1 and 2 ranks.
"""
import dataclasses
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat, simulate
from sdm_dolfinx.cli import main as cli_main
from sdm_dolfinx.contact.friction import make as make_friction
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.equilibrium import StaticStartError
from sdm_dolfinx.problems import ProblemInputError, block, load_file, membrane

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]
INCLINE = ROOT / "demos" / "incline_problem.py"
G = 9810.0
#: the solves' relative tolerance (solvers.active_set: KSP rtol 1e-12) times a safety factor of 10
KSP_SLACK = 1e-11


def slack(dt, m, u_max):
    """What a step's linear solve may leave in the sum of the multipliers (N, per mm of thickness
    in 2-D): KSP_SLACK times |b|_1 ~ m (alpha^2 |U|max + g), alpha = 2/dt (M has row sums of total m)."""
    return KSP_SLACK * m * ((2.0 / dt) ** 2 * u_max + G)


def incline(**values):
    return load_file(INCLINE).problem(COMM, **values)


def global_max(a):
    return COMM.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


@pytest.mark.parametrize("pair,kind", [("P2/P1", "vertices"), ("P2/P1", "nodes"), ("P1+/P0", "vertices")])
def test_problem_file_block_rests_as_the_builtin_block(pair, kind):
    """incline_problem.py at theta = 0 is the built-in block's mesh, material (nu = 0) and load;
    both start at their equilibrium at rest, frictionless, 20 steps of 1e-4 s. The file's run stays
    at U_s (|U^20 - U^0| <= 1e-10 |U^0|: the solves' round-off), every bottom vertex in contact,
    the foundation carrying m g at every step (within :func:`slack`, ~2e-10 m g), zero momentum.
    The built-in solves its static problem otherwise (u_x = 0 at one bottom vertex, bilateral
    bottom) and the file's is the Signorini loop with the centre of mass held along x: the two
    differ by a rigid translation along x (A e_x = 0, e_x^T L = 0) and give the same time series to
    round-off (contact force, u_probe, lambda_probe, energy: 1e-10 relative)."""
    dt, T = 1e-4, 2e-3
    m = 1e-6 * 20.0 * 10.0
    mine = simulate(incline(width=20.0, height=10.0, n=10, nu=0.0, theta=0.0), pair=pair, dt=dt, T=T,
                    constrain=kind)
    ref = simulate(block.problem(COMM, v0=0.0), pair=pair, dt=dt, T=T, constrain=kind)
    U0, _ = mine.discretisation.initial_state()
    ts, tr = mine.timeseries, ref.timeseries
    assert global_max(mine.U.array - U0.array) <= 1e-10 * global_max(U0.array)
    assert np.all(ts["n_active"] == tr["n_active"]) and tr["n_active"][1] == (11 if kind == "vertices" else 21)
    assert np.max(np.abs(ts["contact_force"][1:] - m * G)) <= slack(dt, m, 1e-3)
    assert np.max(np.abs(ts["momentum_x"])) <= 1e-12 * m * G * T
    scales = {"contact_force": m * G, "u_probe": global_max(U0.array), "lambda_probe": np.max(tr["lambda_probe"]),
              "energy": np.max(np.abs(tr["energy"]))}
    for col, scale in scales.items():
        assert np.max(np.abs(ts[col] - tr[col])) <= 1e-10 * scale, col
    dU = mine.U.array - ref.U.array                             # a rigid translation along x
    assert global_max(dU[1::2]) <= 1e-14
    dx = dU[0::2]
    spread = COMM.allreduce(float(np.max(dx, initial=-np.inf)), op=MPI.MAX) \
        - COMM.allreduce(float(np.min(dx, initial=np.inf)), op=MPI.MIN)
    assert spread <= 1e-14, spread


@pytest.mark.parametrize("dim,pair,n,kind", [(2, "P2/P1", 4, "vertices"), (3, "P1/P1", 2, "vertices"),
                                              (2, "P2/P1", 4, "weighted"), (3, "P2/P1", 2, "weighted")])
def test_sticking_block_on_an_incline_does_not_creep(dim, pair, n, kind):
    """A 10 mm block (square in 2-D, cube in 3-D; nu = 0.3) on a 30 degree incline with Coulomb
    mu = 0.8 > tan 30 = 0.577: a rigid block sticks. From u0 = "equilibrium" (the static solution
    with the active nodes sticking, the contact edge's nodes slipping at the cone, the uphill
    corner lifted) at rest, 10 steps of 1e-4 s: the displacement changes by at most 1e-9 mm (the
    static loop stops at a relative 1e-10 of the load; measured <= 2e-14 mm), the foundation carries
    m g cos theta normally and m g sin theta tangentially at every step (within :func:`slack`), the
    momentum stays 0. From rest (--start rest) the same run moves by more than 1e-4 mm (measured
    2e-3 to 3e-3 mm: it rattles and creeps), so the bound is no tautology. With the weighted gap (its
    rows held by multipliers, friction on its tangential rows: sdm_dolfinx.method.static_rows) the same:
    measured 1.6e-16 mm (2-D) and 2.8e-15 mm (3-D, P2/P1), forces within 1e-13 relative."""
    dt, T, theta = 1e-4, 1e-3, np.radians(30.0)
    m = 1e-6 * 10.0 ** dim
    moves = {}
    for start in ("equilibrium", "rest"):
        res = simulate(incline(dim=dim, n=n, start=start), pair=pair, dt=dt, T=T, friction="coulomb",
                       friction_options={"mu": 0.8}, constrain=kind)
        U0, _ = res.discretisation.initial_state(make_friction("coulomb", mu=0.8))
        moves[start] = global_max(res.U.array - U0.array)
        if start == "equilibrium":
            ts = res.timeseries
            tangential = ts["tangential_force"] if dim == 2 else ts["tangential_force_x"]
            assert np.max(np.abs(ts["contact_force"][1:] - m * G * np.cos(theta))) <= slack(dt, m, 1e-3)
            assert np.max(np.abs(np.abs(tangential[1:]) - m * G * np.sin(theta))) <= slack(dt, m, 1e-3)
            # round-off of the solves against the impulse of gravity over the run: dolfinx 0.9 on 2 ranks
            # (MUMPS) measured 1.4e-12 of it (3-D, weighted), above the 1e-12 held before
            assert np.max(np.abs(ts["momentum_x"])) <= 1e-10 * m * G * T
    assert moves["equilibrium"] <= 1e-9, moves
    assert moves["rest"] > 1e-4, moves


def test_membrane_starts_at_its_static_obstacle_solution():
    """The membrane (scalar u, u = 0.02 on the boundary, f = -0.6, obstacle u >= 0; N = 8, P1/P1):
    the static obstacle problem -Laplace u = f, u >= 0, has a contact zone in the middle (the
    unconstrained solution 0.02 + 0.6 x(1-x) y(1-y) ... dips below 0: f pushes 30 times the boundary
    value). U_s satisfies the discrete complementarity (gap >= 0, reaction A U - L >= 0 at the
    constrained vertices, their product 0, round-off 1e-12) and the Dirichlet data, and the run
    from it at rest keeps U = U_s (1e-10 relative) over 10 steps."""
    p = membrane.problem(COMM, N=8)
    p.u0 = "equilibrium"
    d = Discretisation(p, "P1/P1")
    U, _ = d.initial_state()
    r = d.A.createVecLeft()
    d.A.mult(U, r)
    r.axpy(-1.0, d.L)
    gap, lam = U.array[d.cdofs] - d.lb, r.array[d.cdofs]
    scale = global_max(d.L.array)
    assert COMM.allreduce(int(np.sum(gap <= 1e-14)), op=MPI.SUM) > 0            # in contact somewhere
    assert global_max(np.minimum(gap, 0.0)) <= 1e-14 and global_max(np.minimum(lam, 0.0)) <= 1e-12 * scale
    assert global_max(gap * lam) <= 1e-12 * scale
    assert global_max(U.array[d.ddofs] - 0.02) <= 1e-15
    res = simulate(p, pair="P1/P1", dt=0.01, T=0.1)
    assert res.info["problem"]["start"].startswith("equilibrium")          # run.json records it
    assert global_max(res.U.array - U.array) <= 1e-10 * global_max(U.array)
    assert np.max(res.timeseries["kinetic"]) <= 1e-20


def test_equilibrium_start_refused_where_the_static_problem_has_no_solution(mpi_tmp_path, capsys):
    """One line each (a ProblemInputError; exit 2 on the command line, nothing written):
    frictionless on the incline (nothing holds the block along x), mu = 0.5 < tan 30 (every node
    in contact slips: the load still works along x), a penalty contact (its equilibrium penetrates),
    a body without constraint nor Dirichlet data under gravity (it falls)."""
    with pytest.raises(StaticStartError, match="no static equilibrium: neither the active contact.*translation "
                                               "along x, and the load works along it"):
        simulate(incline(), dt=1e-4, T=1e-4)
    with pytest.raises(StaticStartError, match="translation along x.*lift off or slip"):
        simulate(incline(), dt=1e-4, T=1e-4, friction="coulomb", friction_options={"mu": 0.5})
    with pytest.raises(StaticStartError, match="contact 'penalty' penetrates"):
        simulate(incline(theta=0.0), dt=1e-4, T=1e-4, contact="penalty", contact_options={"penalty": 1e4})
    free = incline(theta=0.0)
    free.constraint_vertices = lambda m: np.zeros(0, dtype=np.int32)
    with pytest.raises(StaticStartError, match="translation along y, and the load works"):
        Discretisation(free, "P2/P1").initial_state()
    out = mpi_tmp_path / "never"
    capsys.readouterr()
    assert cli_main(["run", "--problem-file", str(INCLINE), "--T", "1e-4", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert "u0 = 'equilibrium': no static equilibrium" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_u0_may_be_a_dolfinx_function_and_no_other_string():
    """u0 given as a fem.Function (here P1, a linear field) is interpolated into W^h (P2 here):
    U^0 equals the interpolant of the same field (exact for a linear field: 1e-15), and a run starts
    from it. A string other than "equilibrium" is refused when the Problem is made."""
    p = incline(theta=0.0, n=4)
    f = fem.Function(compat.function_space(p.mesh, compat.element("Lagrange", compat.cell_name(p.mesh), 1, (2,))))
    field = lambda x: np.vstack([1e-3 * x[0], 0.01 + 2e-3 * x[1]])          # noqa: E731 (above the foundation)
    f.interpolate(field)
    p.u0 = f
    d = Discretisation(p, "P2/P1")
    U, _ = d.initial_state()
    expect = fem.Function(d.W)
    expect.interpolate(field)
    assert global_max(U.array - expect.x.array[:len(U.array)]) <= 1e-15
    res = simulate(p, pair="P2/P1", dt=1e-4, T=2e-4)
    assert abs(res.timeseries["u_probe"][0] - 0.01) <= 1e-15
    with pytest.raises(ProblemInputError, match="u0 must be x -> values, a dolfinx Function or 'equilibrium'"):
        dataclasses.replace(p, u0="equilibrum")


def test_dirichlet_data_and_a_time_dependent_load():
    """The incline file's block at theta = 0 with its top face clamped (u = 0) and lifted 0.5 mm
    above the floor (lower_bound - 0.5: no contact at rest), under a load (1 + 3 t) rho g that
    grows in time: the static solution is the clamped block hanging under L(0) = rho g, A U = L at
    every dof but the clamped ones (1e-10 of the load), U = 0 on the top face, no constrained node
    touching (every gap > 0.4 mm); a load at t = 0 three times smaller than at t = 1 is what it is
    solved for (U scales with the load: the same U as with the constant load rho g, 1e-12)."""

    def clamped(time_dependent):
        p = incline(theta=0.0, n=4)
        fdim = p.mesh.topology.dim - 1
        p.dirichlet_facets = lambda m: dmesh.locate_entities_boundary(m, fdim, lambda x: np.isclose(x[1], 10.0))
        p.dirichlet_value = lambda x: np.zeros((2, x.shape[1]))
        p.lower_bound = lambda x: -x[1] - 0.5
        if time_dependent:
            t = fem.Constant(p.mesh, 0.0)
            load = p.l
            p.time, p.l = t, lambda w: (1.0 + 3.0 * t) * load(w)
        return p

    d = Discretisation(clamped(True), "P2/P1")
    U, _ = d.initial_state()
    r = d.A.createVecLeft()
    d.A.mult(U, r)
    r.axpy(-1.0, d.L)
    free = np.setdiff1d(np.arange(len(U.array)), d.ddofs)
    assert global_max(r.array[free]) <= 1e-10 * global_max(d.L.array)
    assert global_max(U.array[d.ddofs]) == 0.0 and global_max(U.array) > 1e-5
    assert COMM.allreduce(float(np.min(U.array[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN) > 0.4
    U_const, _ = Discretisation(clamped(False), "P2/P1").initial_state()
    assert global_max(U.array - U_const.array) <= 1e-12 * global_max(U.array)


def test_tresca_friction_holds_the_block_on_the_incline():
    """Tresca (a threshold s = 0.2 N/mm^2 per unit length of the bottom: its capacity s L = 2 N per
    mm exceeds the tangential load m g sin 30 = 0.49 N per mm) on the 2-D incline: the equilibrium
    start stays at rest (10 steps: displacement change <= 1e-9 mm, momentum 0, friction force
    m g sin theta within :func:`slack`)."""
    dt, T, theta, m = 1e-4, 1e-3, np.radians(30.0), 1e-6 * 100.0
    res = simulate(incline(n=4), pair="P2/P1", dt=dt, T=T, friction="tresca",
                   friction_options={"tresca_threshold": 0.2})
    U0, _ = res.discretisation.initial_state(make_friction("tresca", threshold=0.2))
    assert global_max(res.U.array - U0.array) <= 1e-9
    ts = res.timeseries
    assert np.max(np.abs(np.abs(ts["tangential_force"][1:]) - m * G * np.sin(theta))) <= slack(dt, m, 1e-3)
    assert np.max(np.abs(ts["momentum_x"])) <= 1e-12 * m * G * T


# ------------------------------------------------------------------------------------ against obstacles
def _slope(theta, rotated):
    from test_obstacle_contact import _block_on_slope
    p, _ = _block_on_slope(theta, rotated)
    return dataclasses.replace(p, u0="equilibrium")


@pytest.mark.parametrize("pair", ["P1+/P0", "P2/P1"])
def test_equilibrium_on_an_inclined_plane_is_the_one_under_tilted_gravity(pair):
    """Against obstacles the static problem is solved in each node's frame (method/equilibrium.py):
    the block of test_obstacle_contact.py on a 20-degree inclined plane (mesh rotated, vertical gravity,
    a HalfSpace obstacle), Coulomb mu = 0.8 > tan 20 (it sticks), against the axis-aligned block under
    gravity rotated by -20 degrees (the unit rows' static loop): the same static problem up to the
    rotation, so the same energies, contact and friction forces at every step (1e-10 of their scale;
    measured 3e-13), and both stay at rest (kinetic energy <= 1e-20 of |E|; measured 1e-28, where the
    unstressed start rattles at 1e-1 of |E|). Without friction the static problem has no solution (the
    load works along the slope) and is refused in one line, as for the unit rows."""
    kw = dict(pair=pair, dt=2e-5, T=1e-3, friction="coulomb", friction_options={"mu": 0.8})
    flat, tilted = (simulate(_slope(20.0, rotated), **kw).timeseries for rotated in (False, True))
    scale = np.max(np.abs(flat["energy"]))
    assert np.max(np.abs(flat["energy"] - tilted["energy"])) <= 1e-10 * scale
    for c in ("contact_force", "tangential_force"):
        assert np.max(np.abs(flat[c] - tilted[c])) <= 1e-10 * np.max(np.abs(flat[c])), c
    assert flat["n_stick"][-1] > 0 and np.all(flat["n_stick"] == tilted["n_stick"])
    assert np.max(tilted["kinetic"]) <= 1e-20 * scale
    with pytest.raises(StaticStartError, match="translation along x.*load works along it"):
        simulate(_slope(20.0, True), pair=pair, dt=2e-5, T=1e-4)


@pytest.mark.parametrize("pair,friction", [("P1+/P0", None), ("P2/P1", "coulomb")])
def test_a_disc_at_the_bottom_of_a_bowl_starts_at_rest(pair, friction):
    """demos/bowl_problem.py with theta0 = 0 (the disc touching the bowl's bottom) from u0 =
    "equilibrium": the bowl carries the disc's weight (its mesh's area times rho g, within 1e-6; measured
    5e-8 frictionless, where the disc rocks at the level below) and
    the disc stays at rest: its largest kinetic energy within 1e-6 of the one from the unstressed start
    (measured 7e-9 frictionless: the static rows are linearised at the reference configuration, the
    run's at U_s, and they differ by O(u_t^2 / R) on the curved bowl; 1e-25 with friction, where the
    contact node does not move tangentially)."""
    spec = load_file(ROOT / "demos" / "bowl_problem.py")
    T0 = spec.problem(COMM).parameters["period"]
    kw = dict(pair=pair, dt=T0 / 1000, T=T0 / 20)
    if friction:
        kw.update(friction=friction, friction_options={"mu": 0.5})
    runs = {}
    for start in ("equilibrium", "rest"):
        p = spec.problem(COMM, theta0=0.0, h=2.0)
        runs[start] = simulate(dataclasses.replace(p, u0="equilibrium") if start == "equilibrium" else p,
                               **kw).timeseries
    area = COMM.allreduce(fem.assemble_scalar(fem.form(1.0 * ufl.dx(domain=p.mesh))), op=MPI.SUM)
    weight = 1e-6 * area * G
    eq = runs["equilibrium"]
    assert np.max(np.abs(eq["contact_force"][1:] - weight)) <= 1e-6 * weight
    assert np.max(eq["kinetic"]) <= 1e-6 * np.max(runs["rest"]["kinetic"])


@pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")   # the vertex rows' sink
@pytest.mark.parametrize("dim,n", [(2, 4), (3, 2)])
def test_weighted_gap_start_is_the_exact_bar_under_its_own_weight(dim, n):
    """incline_problem.py at theta = 0 with nu = 0, P2/P1 and ``constrain="weighted"`` (the static loop
    on general rows, sdm_dolfinx.method.static_rows). The exact solution: a bar on a frictionless
    foundation under its own weight, u_c(x) = -(rho g / E)(H x_c - x_c^2 / 2), the other components 0
    (nu = 0), is quadratic, so in W^h; it satisfies the discrete problem: A U - L is the consistent
    force of the uniform pressure rho g H on the foundation, int p phi_j ds = sum_i mu_i G_ij with
    mu_i = p int psi_i ds >= 0 (sum_i psi_i = 1 on the face), and G U = 0 = g. So U_s is its
    interpolant to round-off (1e-9 of its largest value), sum mu = m g; the vertex constraint, whose
    rows leave P2's mid-edge nodes free, is not (its face sinks: the bound is no tautology). The run
    from U_s at rest stays there (1e-10), carrying m g at every step (within :func:`slack`)."""
    dt, T, H, E, rho = 1e-4, 1e-3, 10.0, 1000.0, 1e-6
    m = rho * 10.0 ** dim
    c = dim - 1
    errors = {}
    for kind in ("weighted", "vertices"):
        res = simulate(incline(dim=dim, n=n, nu=0.0, theta=0.0), pair="P2/P1", dt=dt, T=T, constrain=kind)
        U0, _ = res.discretisation.initial_state()
        exact = fem.Function(res.discretisation.W)

        def field(x):
            v = np.zeros((dim, x.shape[1]))
            v[c] = -(rho * G / E) * (H * x[c] - 0.5 * x[c] ** 2)
            return v
        exact.interpolate(field)
        nown = len(U0.array)
        errors[kind] = global_max(U0.array - exact.x.array[:nown]) / global_max(exact.x.array[:nown])
        if kind == "weighted":
            ts = res.timeseries
            assert global_max(res.U.array - U0.array) <= 1e-10 * global_max(U0.array)
            assert np.max(np.abs(ts["contact_force"][1:] - m * G)) <= slack(dt, m, 1e-3)
            assert np.max(ts["kinetic"]) <= 1e-20 and np.min(ts["gap_min_boundary"]) >= -1e-12
    assert errors["weighted"] <= 1e-9 and errors["vertices"] > 1e-3, errors


def test_weighted_gap_start_refuses_a_body_nothing_holds():
    """Frictionless on the 30 degree incline, the weighted rows hold the block normally only: the load
    works along x, no static solution (one line, as with the vertex constraint); with mu = 0.5 < tan 30
    every row slips and the load still works along x."""
    with pytest.raises(StaticStartError, match="no static equilibrium: neither the active contact .frictionless, "
                                               "weighted gap. nor Dirichlet data fix the translation along x"):
        simulate(incline(), dt=1e-4, T=1e-4, constrain="weighted")
    with pytest.raises(StaticStartError, match="friction .weighted gap. and Dirichlet data do not fix the "
                                               "translation along x.*lift off or slip"):
        simulate(incline(), dt=1e-4, T=1e-4, constrain="weighted", friction="coulomb", friction_options={"mu": 0.5})
