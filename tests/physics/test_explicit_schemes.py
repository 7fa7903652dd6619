"""The explicit schemes (schemes/explicit.py): central differences, Paoli-Schatzman,
Taylor-Flanagan, and the CFL bound they are refused beyond.

Facts tested, each against an independent route: the measured CFL bound equals the closed-form
largest eigenvalue of the P1 rod (lumped: (4/h^2) cos^2(pi/(4N)); consistent: (6/h^2)(1 - cos t)
/(2 + cos t), t = pi - pi/(2N): the free end mirrored into a fixed-fixed chain of 2N cells) and
the dense eigenvalue with a penalty spring; the refusal fires just beyond it, and the run is
stable just below and blows up just beyond; central differences conserve their shadow energy
1/2 V^{n+1/2}.M V^{n+1/2} + 1/2 U^n.A U^{n+1} - L.(U^n + U^{n+1})/2 to round-off and converge at
order 2; Paoli-Schatzman with e = 0 is central differences with the constraint on U^{n+1}, and a
vertex reaching the obstacle stays there (zero rebound), with e = 1 it bounces back; every exact
scheme satisfies its constraint on its constrained iterate; the quasi-static contact of a
massless contact node is a complementarity; Taylor-Flanagan stops a penetrating vertex.
"""
from mpi4py import MPI

import numpy as np
import pytest
import scipy.linalg

from sdm_dolfinx.contact import penalty as _penalty
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.contact.friction import Friction
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.schemes import explicit
from sdm_dolfinx.problems import membrane, rod1d

COMM = MPI.COMM_WORLD
EXPLICIT = ("central-difference", "paoli-schatzman", "taylor-flanagan")
pytestmark = pytest.mark.skipif(COMM.size > 1, reason="serial checks (tests/parallel compares the ranks)")


def rod(mass="row-sum", NX=20):
    return Discretisation(rod1d.problem(COMM, NX=NX), "P1/P1", mass)


def run(d, scheme, dt, steps, scheme_options=None, **kw):
    """Per step: the contact dof's U, the step's info, lam, active; energies; final U, V."""
    integ = Integrator(d, scheme, dt=dt, scheme_options=scheme_options, **kw)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    c = d.cdofs[0] if len(d.cdofs) else 0
    rec = {k: [] for k in ("u", "lam", "active", "gap_imposed", "gap_end", "E", "U")}
    rec["E"].append(sum(integ.energies(U, V)))
    rec["U"].append(U.array.copy())
    for n in range(steps):
        info = integ.step(U, V, n, n * dt)
        rec["u"].append(U.array[c])
        rec["lam"].append(float(np.sum(integ.lam)))
        rec["active"].append(bool(np.any(integ.active)))
        rec["gap_imposed"].append(info["gap_imposed"])
        rec["gap_end"].append(info["gap_end"])
        rec["E"].append(sum(integ.energies(U, V)))
        rec["U"].append(U.array.copy())
    out = {k: np.array(v) for k, v in rec.items()}
    out.update(V=V.array.copy(), cfl=getattr(integ, "cfl", None), stateful=integ.stateful)
    integ.destroy()
    return out


def cfl_of(d, scheme="central-difference", **kw):
    integ = Integrator(d, scheme, dt=1e-12, **kw)
    cfl = dict(integ.cfl)
    integ.destroy()
    return cfl


# ------------------------------------------------------------------------------ the CFL bound
@pytest.mark.parametrize("mass", ["row-sum", "standard"])
def test_cfl_bound_is_the_rods_closed_form(mass):
    N = 20
    h, theta = 1.0 / N, np.pi - np.pi / (2 * N)
    exact = (4 / h ** 2 * np.cos(np.pi / (4 * N)) ** 2 if mass == "row-sum"
             else 6 / h ** 2 * (1 - np.cos(theta)) / (2 + np.cos(theta)))
    cfl = cfl_of(rod(mass, N))
    assert cfl["omega_max"] ** 2 == pytest.approx(exact, rel=1e-8)
    assert cfl["dt_max"] == pytest.approx(2 / np.sqrt(exact), rel=1e-8)


def test_cfl_bound_with_a_penalty_is_the_dense_eigenvalue():
    """With contact='penalty' the bound includes the spring k = penalty x A_00/m_0 x m_0 at the
    contact node (the treatment's force linearised with the constraint active): the largest
    generalised eigenvalue of (A + k e_0 e_0^T, M) on the free dofs, by LAPACK."""
    d = rod("row-sum")
    cfl = cfl_of(d, contact="penalty", contact_options={"penalty": 3.0})
    free = np.setdiff1d(np.arange(d.A.getSize()[0]), d.ddofs).astype(np.int32)
    A, M = d.A.getValues(free, free), d.M.getValues(free, free)
    c = int(np.flatnonzero(free == d.cdofs[0])[0])
    A[c, c] += 3.0 * _penalty.stiffness_scale(d) * d.cmeasure[0]
    assert cfl["omega_max"] ** 2 == pytest.approx(scipy.linalg.eigh(A, M, eigvals_only=True)[-1], rel=1e-8)


@pytest.mark.parametrize("scheme", EXPLICIT)
def test_cfl_refusal_fires_just_beyond_the_bound(scheme):
    d = rod("row-sum")
    dt_max = cfl_of(d)["dt_max"]
    with pytest.raises(DiscretisationError) as e:
        Integrator(d, scheme, dt=dt_max * (1 + 1e-7))
    assert "CFL" in str(e.value) and "\n" not in str(e.value) and f"{dt_max:.6g}" in str(e.value)
    Integrator(d, scheme, dt=dt_max * (1 - 1e-7)).destroy()


def test_the_bound_is_the_stability_limit(monkeypatch):
    """The membrane (no obstacle, row-sum mass), 300 steps: at 0.98 x dt_max the energy stays
    within 5 % of its initial value; at 1.02 x dt_max (the check switched off) it grows by more
    than 1e6 (the highest mode, seeded by round-off, grows by |z| = 1.49 per step)."""
    d = Discretisation(membrane.problem(COMM, N=6, with_obstacle=False), "P1/P1", "row-sum")
    dt_max = cfl_of(d)["dt_max"]
    monkeypatch.setattr(explicit, "CFL_SAFETY", 2.0)
    stable = run(d, "central-difference", 0.98 * dt_max, 300)["E"]
    unstable = run(d, "central-difference", 1.02 * dt_max, 300)["E"]
    assert np.abs(stable - stable[0]).max() <= 0.05 * abs(stable[0])
    assert np.abs(unstable).max() > 1e6 * abs(unstable[0])


# ------------------------------------------------------------------------------ central differences
def shadow_energy(d, U, dt):
    """1/2 V^{n+1/2}.M V^{n+1/2} + 1/2 U^n.A U^{n+1} - L.(U^n + U^{n+1})/2 for consecutive U's."""
    A = d.A.getValues(range(U.shape[1]), range(U.shape[1]))
    M = d.M.getValues(range(U.shape[1]), range(U.shape[1]))
    L = d.L.array
    V = np.diff(U, axis=0) / dt
    return np.array([0.5 * V[k] @ M @ V[k] + 0.5 * U[k] @ A @ U[k + 1] - L @ (U[k] + U[k + 1]) / 2
                     for k in range(len(V))])


@pytest.mark.parametrize("mass", ["standard", "row-sum"])
def test_central_difference_conserves_its_shadow_energy(mass):
    """M (U^{n+1} - 2 U^n + U^{n-1})/dt^2 = L - A U^n, dotted with (U^{n+1} - U^{n-1})/2: the
    shadow energy is exact; the energy J stays within O((omega dt)^2) of it (bounded: 2 %)."""
    d = Discretisation(membrane.problem(COMM, N=6, with_obstacle=False), "P1/P1", mass)
    dt = 0.5 * cfl_of(d)["dt_max"]
    r = run(d, "central-difference", dt, 400)
    Es = shadow_energy(d, r["U"], dt)
    assert np.abs(Es - Es[0]).max() <= 1e-12 * abs(Es[0])
    assert np.abs(r["E"] - r["E"][0]).max() <= 0.02 * abs(r["E"][0])


def test_central_difference_second_order():
    d = Discretisation(membrane.problem(COMM, N=6, with_obstacle=False), "P1/P1", "row-sum")
    T, dt0 = 0.3, cfl_of(d)["dt_max"] / 2
    dts = [dt0 / 2 ** k for k in range(3)]
    steps = [int(round(T / dt)) for dt in dts]
    dts = [T / s for s in steps]
    ref = run(d, "central-difference", T / (steps[-1] * 8), steps[-1] * 8)["U"][-1]
    errs = [np.linalg.norm(run(d, "central-difference", dt, s)["U"][-1] - ref) for dt, s in zip(dts, steps)]
    order = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert abs(order - 2.0) <= 0.15, (order, errs)


def test_massless_contact_node_is_a_quasi_static_complementarity():
    """Redistributed mass (node 0 massless): at every step (A U - L)_0 = lam >= 0, U_0 >= 0,
    lam U_0 = 0 to round-off, and over the contact phase lam is the exact stress 1/2 (10 %)."""
    d = rod("redistributed")
    dt = 0.9 * cfl_of(d)["dt_max"]
    steps = int(2.2 / dt)
    r = run(d, "central-difference", dt, steps)
    A = d.A.getValues(range(d.A.getSize()[0]), range(d.A.getSize()[0]))
    c = d.cdofs[0]
    residual = np.array([(A @ U)[c] - d.L.array[c] for U in r["U"][1:]])
    scale = np.abs(residual).max()
    assert np.abs(residual - r["lam"]).max() <= 1e-10 * scale
    assert r["u"].min() >= -1e-14 and r["lam"].min() >= 0.0
    assert np.abs(r["u"] * r["lam"]).max() <= 1e-12 * scale
    t = dt * np.arange(1, steps + 1)
    assert abs(r["lam"][(t > 1.1) & (t < 1.9)].mean() - 0.5) <= 0.05


# ------------------------------------------------------------------------------ Paoli-Schatzman
def test_paoli_schatzman_e0_is_central_difference():
    """e = 0: the LCP in (U^{n+1} + 0 U^{n-1}) with U^{n-1} rebuilt from (U^n, V^n) is the
    forward-increment central-difference step (both formulas, same trajectory to round-off)."""
    d = rod("standard")
    dt = 0.5 * cfl_of(d)["dt_max"]
    steps = int(2.2 / dt)
    a, b = run(d, "central-difference", dt, steps), run(d, "paoli-schatzman", dt, steps, {"restitution": 0.0})
    assert not a["stateful"] and not b["stateful"]          # U^{n-1} is rebuilt from (U^n, V^n)
    assert np.abs(a["U"] - b["U"]).max() <= 1e-12
    assert np.abs(a["lam"] - b["lam"]).max() <= 1e-9 * np.abs(a["lam"]).max()
    assert np.count_nonzero(a["active"]) > 0.4 / dt                 # it went through the contact


@pytest.mark.parametrize("mass", ["row-sum", "standard"])
def test_paoli_schatzman_zero_rebound(mass):
    """e = 0: the contact vertex reaches the obstacle once and stays: after the arrival step it is
    active at every step until it leaves near t = 2 (the exact release), and its velocity over
    each step with contact at both ends, (U^{n+1} - U^n)_0/dt, is 0 to round-off; e = 1: it
    bounces back at once, with the speed it arrived with (20 %)."""
    d = rod(mass)
    dt = 2e-3
    steps = int(2.5 / dt)
    t = dt * np.arange(1, steps + 1)
    r = run(d, "paoli-schatzman", dt, steps)
    act, u = r["active"], r["u"]
    first = int(np.argmax(act))
    release = first + int(np.argmin(act[first:]))
    assert abs(t[first] - 1.0) <= 0.01 and abs(t[release] - 2.0) <= 0.05
    assert act[first:release].all()
    assert np.abs(np.diff(u[first:release])).max() <= 1e-14
    bounce = run(d, "paoli-schatzman", dt, steps, {"restitution": 1.0})
    act, u = bounce["active"], bounce["u"]
    k = int(np.argmax(act))
    arrival = (u[k - 2] - u[k - 3]) / dt
    leave = k + int(np.argmin(act[k:]))
    assert leave - k <= 3
    assert (u[leave + 2] - u[leave + 1]) / dt == pytest.approx(-arrival, rel=0.2)


# ------------------------------------------------------------------------------ Taylor-Flanagan
def test_taylor_flanagan_stops_a_penetrating_vertex():
    """Row-sum mass: at every step where the predictor would take the contact vertex below the
    obstacle, the contact force stops it (U^{n+1}_0 = U^n_0, GetFEM's V = 0) and pushes (> 0);
    it never goes below the obstacle."""
    d = rod("row-sum")
    dt = 2e-3
    steps = int(2.2 / dt)
    r = run(d, "taylor-flanagan", dt, steps)
    u = np.concatenate([[r["U"][0][d.cdofs[0]]], r["u"]])
    stopped = np.flatnonzero(r["lam"] > 0)
    assert len(stopped) > 0.5 / dt
    assert np.abs(u[stopped + 1] - u[stopped]).max() <= 1e-15
    assert r["gap_end"].min() >= 0.0


# ------------------------------------------------------------------------------ every exact scheme
CASES = [("midpoint", "standard", None), ("backward-euler", "standard", None), ("newmark", "standard", None),
         ("newmark", "redistributed", None), ("hht", "row-sum", {"hht_alpha": -0.3}),
         ("central-difference", "standard", None), ("central-difference", "row-sum", None),
         ("central-difference", "redistributed", None), ("paoli-schatzman", "standard", {"restitution": 0.5}),
         ("paoli-schatzman", "row-sum", {"restitution": 1.0}), ("taylor-flanagan", "standard", None),
         ("taylor-flanagan", "row-sum", None)]


@pytest.mark.parametrize("scheme,mass,options", CASES)
def test_constraint_holds_on_the_constrained_iterate(scheme, mass, options):
    """Through the rod's first contact phase: the constrained iterate (U^{n+1/2}, U^{n+1},
    (U^{n+1} + e U^{n-1})/(1 + e), Taylor-Flanagan's U^{n+1} - U^n where it would penetrate) is
    never below its bound by more than round-off."""
    d = rod(mass)
    r = run(d, scheme, 2e-3, 1100, options)
    assert r["gap_imposed"].min() >= -1e-13
    assert np.count_nonzero(r["active"]) >= 10          # it met the obstacle (chattering: a few steps)


# ------------------------------------------------------------------------------ refusals
def test_refusals_are_one_line():
    md = Discretisation(membrane.problem(COMM, N=4), "P1+/P0")
    mc = Discretisation(membrane.problem(COMM, N=4), "P1+/P1", "consistent")
    table = [(md, "central-difference", {}, "singular away from the contact"),
             (rod("redistributed"), "paoli-schatzman", {}, "without mass"),
             (rod("redistributed"), "taylor-flanagan", {}, "without mass"),
             (rod("redistributed"), "central-difference", {"contact": "penalty"}, "needs a mass at every dof"),
             (rod("row-sum"), "taylor-flanagan", {"vi_solver": "vinewtonrsls"}, "semi-smooth Newton"),
             (rod("row-sum"), "paoli-schatzman", {"contact": "penalty"}, "contact must be 'exact'"),
             (rod("row-sum"), "taylor-flanagan", {"contact": "nitsche"}, "contact must be 'exact'"),
             (mc, "newmark", {}, "M formulation"), (mc, "central-difference", {}, "M formulation"),
             (mc, "midpoint", {"contact": "penalty"}, "M formulation")]
    for d, scheme, kw, words in table:
        with pytest.raises(DiscretisationError) as e:
            Integrator(d, scheme, dt=1e-4, **kw)
        assert words in str(e.value) and "\n" not in str(e.value), (scheme, kw, str(e.value))
    with pytest.raises(DiscretisationError, match="no frictional step"):
        Integrator(Discretisation(membrane.problem(COMM, N=4), "P1/P1"), "central-difference", dt=1e-4,
                   friction=Friction("tresca", threshold=1.0))
    for scheme, opts in [("paoli-schatzman", {"restitution": 1.5}), ("paoli-schatzman", {"restitution": -0.1}),
                         ("central-difference", {"restitution": 0.5}), ("taylor-flanagan", {"hht_alpha": -0.1})]:
        with pytest.raises(ValueError) as e:
            Integrator(rod("row-sum"), scheme, dt=1e-4, scheme_options=opts)
        assert "\n" not in str(e.value)
