"""The 1-D rod's contact point under the midpoint scheme (sdm_dolfinx/validation/rod_contact.py): U^{n+1}(0)
alternates +-d in the sustained contact with d the massless mode's amplitude e(0), set by the interpolated
initial state and independent of dt; the energy changes by exactly the contact force's work on U^{n+1} - U^n;
started from Pi U_0 (the semi-discrete solution at t = 0+) the dip is O(dt) and the energy constant.

Each test says why the number is what it is (the derivation is the module's docstring)."""
import json
import math

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import simulate
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.problems import rod1d
from sdm_dolfinx.report import rod_contact_entry
from sdm_dolfinx.study.entry import Verdict
from sdm_dolfinx.validation import rod_contact as rc

COMM = MPI.COMM_WORLD
V = rc.V_IMPACT


@pytest.fixture(scope="module")
def rows():
    """The study's 8 runs (NX = 20, T = 2.1; P2/P1 and P1+/P0, dt = 2e-3 and 1e-3, both starts)."""
    return {(r["pair"], r["start"], r["dt"]): r for r in rc.study(comm=COMM)}


@pytest.mark.parametrize("pair", rc.PAIRS)
@pytest.mark.parametrize("nx", [20, 40])
def test_mode_amplitude_closed_form(pair, nx):
    """e = U_0 - Pi U_0 minimises 1/2 a(w, w) + w(0)/2 over Ker B: e(0) = h/(4 sqrt 3) (P1+/P0, derived from the
    vertex recurrence w_{i+1} + 4 w_i + w_{i-1} = 0) and h/(4 sqrt 15) (P2/P1); at the minimiser a(w, w) =
    -w(0)/2, so the energy it holds is delta = e(0)/4. The finite rod differs from the semi-infinite one by
    (2 - sqrt 3)^NX ~ 1e-12 (P1+/P0)."""
    _, _, e0, delta = rc.relaxed_start(pair, nx)
    assert e0 == pytest.approx(rc.mode_amplitude(pair, 1.0 / nx), rel=1e-10)
    assert delta == pytest.approx(e0 / 4, rel=1e-9)


@pytest.mark.parametrize("pair", rc.PAIRS)
def test_projection_agrees_with_the_package_matrices(pair):
    """The projection assembled in numpy (rod_contact.relaxed_start) and the one computed from the package's A
    and B (KKT of min 1/2 U^T A U over B U = B U_0, x = 1 fixed) move the contact dof by the same e(0), and the
    package's interpolant U_0 has no Ker B component only away from the free end's relaxation (J drops by
    delta). Also: the contact dof has a mass of its own (M_00 = h/18 for P2/P1 with the lumped C, h/36 for
    P1+/P0): what is massless is a mode through it."""
    if COMM.size > 1:
        pytest.skip("dense matrices of one rank")
    nx = 20
    d = Discretisation(rod1d.problem(COMM, NX=nx), pair)

    def dense(m):
        r, c = m.getSize()
        return m.getValues(range(r), range(c))
    A, B, M = dense(d.A), dense(d.B), dense(d.M)
    U0, _ = d.initial_state()
    free = np.setdiff1d(np.arange(A.shape[0]), d.ddofs)
    Af, Bf, u0 = A[np.ix_(free, free)], B[:, free], U0.array[free]
    nh = Bf.shape[0]
    kkt = np.block([[Af, Bf.T], [Bf, np.zeros((nh, nh))]])
    sol = np.linalg.lstsq(kkt, np.r_[np.zeros(len(free)), Bf @ u0], rcond=None)[0]
    U = sol[:len(free)]
    c = int(np.searchsorted(free, d.cdofs[0]))
    _, _, e0, delta = rc.relaxed_start(pair, nx)
    assert u0[c] - U[c] == pytest.approx(e0, rel=1e-9)
    assert 0.5 * u0 @ Af @ u0 - 0.5 * U @ Af @ U == pytest.approx(delta, rel=1e-9)
    assert M[d.cdofs[0], d.cdofs[0]] == pytest.approx((1 / 18 if pair == "P2/P1" else 1 / 36) / nx, rel=1e-12)


@pytest.mark.slow
def test_interpolant_start_alternates_by_e0_whatever_dt(rows):
    """From the interpolant (every run): in flight u(0) carries (-1)^n e(0) (second difference / 4 = e(0) within
    1 %); in contact U^{n+1/2}(0) = 0 so U^{n+1}(0) = -U^n(0) (to the solver's tolerance) with |u(0)| = e(0)
    within v dt (the impact's kick, v = 1/2): the dip does not shrink with dt."""
    for pair in rc.PAIRS:
        e0 = rc.mode_amplitude(pair, 1.0 / rc.NX)
        for dt in rc.DTS:
            r = rows[(pair, "interpolant", dt)]
            assert r["flight_alternation"] == pytest.approx(e0, rel=0.01), (pair, dt)
            assert r["antisymmetry"] < 1e-9, (pair, dt)
            assert abs(r["dip_min"] - e0) <= V * dt and abs(r["dip_max"] - e0) <= V * dt, (pair, dt)
        coarse, fine = (rows[(pair, "interpolant", dt)]["dip_max"] for dt in rc.DTS)
        assert fine > 0.9 * coarse, pair             # halving dt leaves the dip where it is


@pytest.mark.slow
def test_energy_changes_by_the_contact_work_on_the_dip(rows):
    """The midpoint scheme's energy identity E^{n+1} - E^n = lambda^{n+1/2} (U^{n+1}(0) - U^n(0)) holds at every
    step to the solver's tolerance (1e-9 of E = 1/8). In flight it is zero (E constant to round-off, 1e-9 over
    ~900 steps); in contact, where U^{n+1}(0) = -U^n(0) = +-d, every step changes E by exactly 2 lambda d with
    alternating sign: the swing. The mode keeps its energy through the contact: after the release E is 1/8
    within delta/2 (the semi-discrete solution's energy is 1/8 - delta)."""
    for r in rows.values():
        assert r["identity"] < 1e-9, (r["pair"], r["start"], r["dt"])
        assert r["energy_flight_drift"] < 1e-9, (r["pair"], r["start"], r["dt"])
    for pair in rc.PAIRS:
        for dt in rc.DTS:
            r = rows[(pair, "interpolant", dt)]
            t, u, E, lam = (np.asarray(r["series"][k]) for k in ("t", "u", "energy", "lambda"))
            assert E[0] == pytest.approx(rod1d.ENERGY, abs=1e-14)
            c = np.flatnonzero((t > rc.CONTACT[0]) & (t < rc.CONTACT[1]))[1:]
            dE = E[c] - E[c - 1]
            assert np.max(np.abs(np.abs(dE) - 2 * lam[c] * r["dip_max"])) < 1e-8, (pair, dt)
            assert np.all(dE[1:] * dE[:-1] < 0), (pair, dt)                    # the sign alternates every step
            assert abs(E[-1] - rod1d.ENERGY) < r["delta"] / 2, (pair, dt)


@pytest.mark.slow
def test_relaxed_start_has_an_O_dt_dip_and_a_constant_energy(rows):
    """From Pi U_0 no mode is excited at t = 0: the flight alternation is below 1e-4 (O(dt^2) of the smooth
    motion), the contact dip is the impact's kick only, below v dt / 2, and the energy starts at 1/8 - delta
    (the semi-discrete problem's energy after its relaxation at t = 0+) and stays within lambda_max v dt of it."""
    for pair in rc.PAIRS:
        for dt in rc.DTS:
            r = rows[(pair, "relaxed", dt)]
            assert r["flight_alternation"] < 1e-4, (pair, dt)
            assert r["dip_max"] <= V * dt / 2, (pair, dt)
            assert r["energy_0"] == pytest.approx(rod1d.ENERGY - r["delta"], abs=1e-12)
            assert all(abs(e - r["energy_0"]) <= r["lambda_max"] * V * dt for e in r["energy_contact"]), (pair, dt)
    assert rc.checks(list(rows.values())) == {k: True for k in rc.checks(list(rows.values()))}


def test_backward_euler_removes_the_mode_in_its_first_step():
    """Backward Euler's stability function 1/(1 - z) is 0 at z = infinity: its first step relaxes the massless
    mode (u(0) then moves smoothly: its second differences / 4 are the smooth motion's dt^2 u''/4, measured
    1.4 % of e(0) just after the start and falling, where the midpoint scheme's are e(0)); the energy drops
    by at least delta at that step."""
    dt = 2e-3
    r = simulate("rod1d", {"NX": rc.NX}, pair="P2/P1", scheme="backward-euler", dt=dt, T=0.5, comm=COMM)
    u, E = np.asarray(r.timeseries["u_probe"]), np.asarray(r.timeseries["energy"])
    second = np.abs(u[3:] - 2 * u[2:-1] + u[1:-2]) / 4
    _, _, e0, delta = rc.relaxed_start("P2/P1", rc.NX)
    assert second.max() < 0.05 * e0
    assert E[0] - E[1] >= delta


def test_entry_verdict_follows_the_checks():
    """The report entry agrees when every prediction holds and says which fail otherwise (a row doctored to a
    dip that shrank with dt makes it 'in part')."""
    base = {"pair": "P2/P1", "start": "interpolant", "dt": 2e-3, "NX": 20, "h": 0.05,
            "e0": rc.mode_amplitude("P2/P1", 0.05), "e0_closed_form": rc.mode_amplitude("P2/P1", 0.05),
            "delta": rc.mode_amplitude("P2/P1", 0.05) / 4, "flight_alternation": rc.mode_amplitude("P2/P1", 0.05),
            "dip_min": 3.12e-3, "dip_max": 3.12e-3, "antisymmetry": 1e-12, "energy_0": 0.125,
            "energy_contact": [0.122, 0.128], "energy_flight_drift": 1e-13, "identity": 1e-13, "lambda_max": 0.9}
    rows = []
    for pair in rc.PAIRS:
        e0 = rc.mode_amplitude(pair, 0.05)
        for start in rc.STARTS:
            for dt in rc.DTS:
                r = dict(base, pair=pair, start=start, dt=dt, e0=e0, e0_closed_form=e0, delta=e0 / 4)
                if start == "relaxed":
                    r.update(flight_alternation=1e-6, dip_min=1e-5, dip_max=1e-5, energy_0=0.125 - e0 / 4,
                             energy_contact=[0.125 - e0 / 4 - 1e-5, 0.125 - e0 / 4 + 1e-5])
                else:
                    r.update(flight_alternation=e0, dip_min=e0, dip_max=e0)
                rows.append(r)
    good = rod_contact_entry.make_entry(rows, True, 1.0)
    assert good.verdict is Verdict.AGREES and "Every prediction holds" in good.ours
    rows[1] = dict(rows[1], dip_min=rows[1]["e0"] / 2, dip_max=rows[1]["e0"] / 2)
    bad = rod_contact_entry.make_entry(rows, True, 1.0)
    assert bad.verdict is Verdict.IN_PART and "dip_not_shrinking" in bad.ours


def test_stored_rows_are_reused_only_for_the_same_definition(mpi_tmp_path):
    """The report reads runs_dir/rod_contact/rod_contact.json only when its key (pairs, dts, starts, NX, T,
    version) is the study's; another key is not read."""
    folder = mpi_tmp_path / "rod_contact"
    if COMM.rank == 0:
        folder.mkdir()
        (folder / rod_contact_entry.ROWS_FILE).write_text(json.dumps({"key": rod_contact_entry.key(), "rows": [1]}))
    COMM.Barrier()
    rows, computed = rod_contact_entry.run_study(folder, COMM, say=lambda s: None)
    assert rows == [1] and computed is False
    COMM.Barrier()
    if COMM.rank == 0:
        other = dict(rod_contact_entry.key(), NX=40)
        (folder / rod_contact_entry.ROWS_FILE).write_text(json.dumps({"key": other, "rows": [1]}))
        assert rod_contact_entry.read_rows(folder) is None


@pytest.mark.parametrize("argv,message", [
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--out", "/proc/sdm_no_such_dir/x"], "cannot write to /proc/sdm_no_such_dir/x"),
])
def test_bad_input_is_one_line(argv, message, capsys):
    """Bad arguments or an unwritable folder: one line on stderr, status 2, nothing run."""
    assert rc.main(argv) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_out_that_is_a_file_is_refused(mpi_tmp_path, capsys):
    f = mpi_tmp_path / "a_file"
    if COMM.rank == 0:
        f.write_text("x")
    COMM.Barrier()
    assert rc.main(["--out", str(f)]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert err.count("\n") == 1 and "is not a folder" in err and f.read_text() == "x"


def test_unknown_pair_is_refused():
    with pytest.raises(rc.RodContactError, match="choose one of P2/P1, P1"):
        rc.relaxed_start("P1/P1")
    with pytest.raises(rc.RodContactError, match="choose one of"):
        rc.mode_amplitude("P1/P0", 0.05)
    assert math.isclose(rc.mode_amplitude("P1+/P0", 1.0), 1 / (4 * math.sqrt(3)))


def test_redistributed_mass_alternates_by_half_a_cell():
    """With the redistributed mass (standard P1, no inertia at the contact node) the massless mode is the contact
    node alone: relaxed statically against its neighbour it moves by h u_x = h/2, so the midpoint scheme's u(0)
    alternates +-h/2 in flight and in contact (comparison.md's 'max penetration' of redistributed-midpoint)."""
    nx, dt = 20, 1.0 / 40
    r = simulate("rod1d", {"NX": nx}, pair="P1/P1", mass="redistributed", scheme="midpoint", dt=dt, T=2.1, comm=COMM)
    m = rc.measure(*(np.asarray(r.timeseries[k], dtype=float) for k in ("t", "u_probe", "energy", "lambda_probe")))
    assert m["flight_alternation"] == pytest.approx(0.5 / nx, rel=0.02)
    assert abs(m["dip_max"] - 0.5 / nx) <= V * dt and m["antisymmetry"] < 1e-9


@pytest.mark.parametrize("name,params,pair", [
    ("membrane", {"N": 10}, "P1+/P0"), ("membrane", {"N": 10}, "P2/P1"), ("disc", {"level": 1}, "P2/P1"),
    ("block", {}, "P2/P1"), ("block", {"start": "rest"}, "P2/P1"), ("ball", {"level": 1}, "P2/P1"),
    ("bar", {}, "P2/P1"), ("rod1d", {}, "P2/P1")])
def test_which_initial_states_excite_the_mode(name, params, pair):
    """U_0 excites the alternating mode when A U_0 - L is not balanced on Ker M by contact reactions at the
    vertices in contact at t = 0 (lambda >= 0): min over lambda of |P_F (A U_0 - L - G lambda)| with P_F the
    projection on Ker M. The built-in problems are balanced to 2e-14 (the dip is then O(dt)); the rod is not
    (0.42: its free end carries the strain -1/2)."""
    if COMM.size > 1:
        pytest.skip("dense matrices of one rank")
    from sdm_dolfinx.problems import registry
    d = Discretisation(registry.get(name).problem(COMM, **params), pair)

    def dense(m):
        r, c = m.getSize()
        return m.getValues(range(r), range(c))
    U0, _ = d.initial_state()
    A = d.A
    r = A.createVecLeft()
    A.mult(U0, r)
    r = r.array - d.L.array
    free = np.setdiff1d(np.arange(len(r)), d.ddofs)
    if np.linalg.norm(r[free]) == 0.0:
        residual = 0.0
    else:
        M = dense(d.M)[np.ix_(free, free)]
        w, Q = np.linalg.eigh(M)
        ker = Q[:, w < 1e-12 * w.max()]
        active = d.cdofs[np.abs(U0.array[d.cdofs] - d.lb) < 1e-12]
        G = np.zeros((len(r), len(active)))
        G[active, np.arange(len(active))] = 1.0
        PG, Pr = ker.T @ G[free], ker.T @ r[free]
        lam = np.linalg.lstsq(PG, Pr, rcond=None)[0] if len(active) else np.zeros(0)
        assert np.all(lam >= -1e-12)
        residual = float(np.linalg.norm(Pr - PG @ lam))
    if name == "rod1d":
        assert residual > 0.4
    else:
        assert residual < 2e-14
