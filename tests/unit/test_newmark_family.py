"""Newmark (beta = 1/4, gamma = 1/2) and HHT-alpha (schemes/newmark.py, hht.py).

Definitions (Newmark 1959; Hilber, Hughes, Taylor 1977), alpha = 0 for Newmark:

  M a^{n+1} + (1 + alpha) A U^{n+1} - alpha A U^n = L + lam^{n+1},
  U^{n+1} = U^n + dt V^n + dt^2/2 ((1 - 2 beta) a^n + 2 beta a^{n+1}),
  V^{n+1} = V^n + dt ((1 - gamma) a^n + gamma a^{n+1}),
  beta = (1 - alpha)^2/4, gamma = (1 - 2 alpha)/2.

Facts tested: the step satisfies these equations (dense numpy, singular M too); Newmark keeps
J = 1/2 V.M V + 1/2 U.A U - U.L to round-off without contact (trapezoidal rule); HHT acts on an
eigenmode of (A, M) exactly as the scalar recursion with omega dt, whose energy decays like the
spectral radius of its amplification matrix (computed here from the definition) squared per step,
(1 + alpha)/(1 - alpha) at omega dt -> infinity; HHT is second order in dt and its energy loss
vanishes like dt^2; on the 1-D rod Newmark with the consistent mass equals a dense transcription
of GetFEM's demo (version 0, beta = 1/4) and shows Doyen-Ern-Piperno's contact-stress oscillations.
"""
from mpi4py import MPI

import numpy as np
import pytest
import scipy.linalg

from sdm_dolfinx import schemes
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.problems import membrane, rod1d

COMM = MPI.COMM_WORLD


def hht_parameters(alpha):
    return (1.0 - alpha) ** 2 / 4.0, (1.0 - 2.0 * alpha) / 2.0


def run(d, scheme, dt, steps, scheme_options=None, U0=None):
    """(U, V, energies J, lam sums, active flags of the first constrained dof) after ``steps``."""
    integ = Integrator(d, scheme, dt=dt, scheme_options=scheme_options)
    U, V = d.initial_state()
    if U0 is not None:
        U.array[:] = U0
    V = integ.initial_velocity(V)
    E, lam = [sum(integ.energies(U, V))], []
    for n in range(steps):
        integ.step(U, V, n, n * dt)
        E.append(sum(integ.energies(U, V)))
        lam.append(COMM.allreduce(float(np.sum(integ.lam)), op=MPI.SUM))
    out = U.array.copy(), V.array.copy(), np.array(E), np.array(lam)
    integ.destroy()
    return out


# ------------------------------------------------------------------------------ definitions
@pytest.mark.parametrize("alpha", [0.0, -0.1, -1.0 / 3.0])
@pytest.mark.parametrize("singular", [False, True])
def test_step_solves_the_hht_equations(alpha, singular):
    """Newmark.coefficients/rhs/update's algebra, transcribed on dense matrices (the scheme's
    formulas, independent of PETSc): the step's X = U^{n+1} and the kinematic a^{n+1} satisfy
    the equation of motion, with M of rank 6 of 12 too (the method's singular M)."""
    rng = np.random.default_rng(3)
    n, dt = 12, 0.05
    beta, gamma = hht_parameters(alpha)
    Bm = rng.standard_normal((6 if singular else n, n))
    M = Bm.T @ Bm
    Q = rng.standard_normal((n, n))
    A = Q @ Q.T + n * np.eye(n)
    L, Un, Vn, an = (rng.standard_normal(n) for _ in range(4))
    s = schemes.get("hht").configure({"hht_alpha": alpha})
    cM, cA = s.coefficients(dt)
    Ut = Un + dt * Vn + dt * dt * (1 - 2 * beta) / 2 * an
    X = np.linalg.solve(cM * M + cA * A, L + alpha * A @ Un + cM * M @ Ut)
    a1 = (X - Ut) / (beta * dt * dt)
    residual = M @ a1 + (1 + alpha) * A @ X - alpha * A @ Un - L
    assert np.abs(residual).max() <= 1e-11 * (np.abs(A @ X).max() + np.abs(L).max())
    assert np.allclose(X, Un + dt * Vn + dt * dt / 2 * ((1 - 2 * beta) * an + 2 * beta * a1), rtol=1e-12, atol=1e-12)
    assert (s.beta, s.gamma, s.hht) == pytest.approx((beta, gamma, alpha), abs=1e-15)


def test_parameters_refused_in_one_line():
    for bad in ({"hht_alpha": 0.1}, {"hht_alpha": -0.34}, {"hht_alpha": "x"}, {"restitution": 0.5}):
        with pytest.raises(ValueError) as e:
            schemes.get("hht").configure(bad)
        assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="has no parameter hht_alpha"):
        schemes.get("newmark").configure({"hht_alpha": -0.1})
    assert schemes.get("newmark").configure({"hht_alpha": None, "restitution": None}).name == "newmark"
    assert schemes.get("newmark").stateful and schemes.get("hht").stateful


def test_block_variant_refused():
    d = Discretisation(membrane.problem(COMM, N=4), "P1+/P1", "consistent")
    with pytest.raises(DiscretisationError, match="M formulation"):
        Integrator(d, "newmark", dt=1e-2)


# ------------------------------------------------------------------------------ energy
@pytest.mark.parametrize("pair", ["P1/P1", "P1+/P0", "P2/P1"])
def test_newmark_conserves_energy_without_contact(pair):
    """J^{n+1} - J^n = (U^{n+1} - U^n).[(M a^n + M a^{n+1})/2 + A (U^n + U^{n+1})/2 - L] = 0:
    to round-off (200 solves with cond(K) ~ 1e2), also for the singular M of P1+/P0, P2/P1
    (whose initial force L is in the range of M: f is constant, H^h holds the constants)."""
    d = Discretisation(membrane.problem(COMM, N=6, with_obstacle=False), pair)
    _, V, E, _ = run(d, "newmark", 0.01, 200)
    assert np.abs(E - E[0]).max() <= 1e-12 * abs(E[0])
    assert COMM.allreduce(float(np.abs(V).max()), op=MPI.MAX) > 0.01       # it moves (not a static run)


def test_hht_alpha_zero_is_newmark():
    d = Discretisation(membrane.problem(COMM, N=6), "P1/P1")
    a = run(d, "newmark", 2e-3, 150)
    b = run(d, "hht", 2e-3, 150, {"hht_alpha": 0.0})
    for x, y in zip(a, b):
        assert np.allclose(x, y, rtol=1e-12, atol=1e-12 * np.abs(x).max())


def _amplification(alpha, W):
    """HHT's amplification matrix of one mode (m = 1, k = W^2, dt = 1) on (u, v, a)."""
    beta, gamma = hht_parameters(alpha)
    k = W * W
    out = np.zeros((3, 3))
    for j in range(3):
        u, v, a = np.eye(3)[j]
        ut = u + v + (0.5 - beta) * a
        u1 = (ut / beta + alpha * k * u) / (1.0 / beta + (1.0 + alpha) * k)
        a1 = (u1 - ut) / beta
        out[:, j] = u1, v + (1 - gamma) * a + gamma * a1, a1
    return out


@pytest.mark.parametrize("Omega", [0.5, 4.0, 50.0])
def test_hht_damps_an_eigenmode_as_its_spectral_radius(Omega):
    """The membrane's highest mode phi (A phi = omega^2 M phi, dense eigensolver here), started
    at rest with dt = Omega / omega: the FE run's energy equals the scalar recursion's (HHT acts
    mode by mode) and decays like rho(Omega)^(2 n), rho the amplification matrix's spectral
    radius ((1 + alpha)/(1 - alpha) = 0.818 for Omega -> infinity, ~1 for resolved modes)."""
    if COMM.size > 1:
        pytest.skip("dense eigenvectors on one rank")
    alpha, steps = -0.1, 60
    d = Discretisation(membrane.problem(COMM, N=4, with_obstacle=False, f=1e-30, g=0.0, u0=0.0), "P1/P1")
    free = np.setdiff1d(np.arange(d.A.getSize()[0]), d.ddofs).astype(np.int32)
    w2, vecs = scipy.linalg.eigh(d.A.getValues(free, free), d.M.getValues(free, free))
    phi, omega = vecs[:, -1], np.sqrt(w2[-1])            # M-normalised: phi.M phi = 1
    U0 = np.zeros(d.A.getSize()[0])
    U0[free] = phi
    _, _, E, _ = run(d, "hht", Omega / omega, steps, {"hht_alpha": alpha}, U0=U0)
    # the scalar recursion with u = 1, v = 0, a = -W^2 (energy 1/2 v^2 + 1/2 W^2 u^2, times omega^2/W^2)
    G = _amplification(alpha, Omega)
    z, Es = np.array([1.0, 0.0, -Omega ** 2]), []
    for _ in range(steps + 1):
        Es.append(0.5 * z[1] ** 2 + 0.5 * Omega ** 2 * z[0] ** 2)
        z = G @ z
    Es = np.array(Es) * omega ** 2 / Omega ** 2
    assert np.allclose(E, Es, rtol=1e-8, atol=1e-8 * E[0])
    rho = np.abs(np.linalg.eigvals(G)).max()
    half = steps // 2                   # past the start's transient (the third, spurious eigenvalue)
    decay = np.log(E[-1] / E[half]) / (2 * (steps - half) * np.log(rho))
    assert E[-1] < E[0] and abs(decay - 1.0) <= 0.1, decay
    if Omega == 50.0:
        assert rho == pytest.approx((1 + alpha) / (1 - alpha), rel=2e-3)


def test_hht_second_order_and_energy_loss_vanishes_like_dt2():
    """U(T) against a run with dt/16: fitted order 2 (within 0.15); the energy lost by T (HHT's
    numerical damping, alpha = -0.3) is positive and decreases at least like dt^2 (measured
    ratios 4.6, 4.4 when dt halves)."""
    d = Discretisation(membrane.problem(COMM, N=6, with_obstacle=False), "P1/P1")
    T, dts = 0.4, [0.02, 0.01, 0.005]
    ref, _, _, _ = run(d, "hht", dts[-1] / 8, int(round(T / (dts[-1] / 8))), {"hht_alpha": -0.3})
    errs, losses = [], []
    for dt in dts:
        U, _, E, _ = run(d, "hht", dt, int(round(T / dt)), {"hht_alpha": -0.3})
        errs.append(np.sqrt(COMM.allreduce(float(np.sum((U - ref) ** 2)), op=MPI.SUM)))
        losses.append(E[0] - E[-1])
    order = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert abs(order - 2.0) <= 0.15, order
    assert all(x > 0 for x in losses)
    assert all(3.5 <= losses[i] / losses[i + 1] <= 5.0 for i in range(2)), losses


# ------------------------------------------------------------------------------ the 1-D rod
def getfem_newmark(NX, dt, steps, beta=0.25, gamma=0.5):
    """GetFEM's demo_dynamic_contact_1D.py, version 0 (pure Signorini), beta > 0, standard P1
    mass, transcribed in dense numpy (nodes x_i = i h, contact at node 0, u(1) = 0): u(0, t_n)
    and the contact force s_n = -Fc1[0] after each step."""
    h, n = 1.0 / NX, NX + 1
    M, K = np.zeros((n, n)), np.zeros((n, n))
    for e in range(NX):
        i = [e, e + 1]
        M[np.ix_(i, i)] += h / 6 * np.array([[2, 1], [1, 2]])
        K[np.ix_(i, i)] += 1 / h * np.array([[1, -1], [-1, 1]])
    for mat in (M, K):
        mat[-1, :] = 0.0
        mat[-1, -1] = 1.0
    U0 = 0.5 - 0.5 * h * np.arange(n)
    MV0, MA0 = np.zeros(n), -K @ U0
    KN = M + dt * dt * beta * K
    KNC = KN.copy()
    KNC[0, :] = 0.0
    KNC[0, 0] = 1.0
    u0, s = [], []
    for _ in range(steps):
        B = M @ U0 + dt * MV0 + dt * dt * (1 - 2 * beta) / 2 * MA0
        U1 = np.linalg.solve(KN, B)
        if U1[0] < 0:
            B2 = B.copy()
            B2[0] = 0.0
            U1 = np.linalg.solve(KNC, B2)
            Fc1 = (KN @ U1 - B) / (beta * dt * dt)
        else:
            Fc1 = np.zeros(n)
        MA1 = Fc1 - K @ U1
        MV0 = MV0 + dt * ((1 - gamma) * MA0 + gamma * MA1)
        MA0, U0 = MA1, U1
        u0.append(U1[0])
        s.append(Fc1[0])
    return np.array(u0), np.array(s)


def test_rod_newmark_equals_getfem_demo_and_oscillates():
    """The rod, P1/P1 consistent mass, dt = 2e-3: u(0, t) agrees with the transcription of
    GetFEM's demo to 1e-10 up to the impact (t = 1) and, with the contact force, to round-off
    amplified by the contact events through the first of them (t <= 1.05: 1e-7, the force to 1e-6
    relative: it is (K X - b)/(beta dt^2), a difference of O(1) terms over 1e-6; the chattering
    contact then amplifies round-off without bound). In the contact phase the force swings far
    from the exact 1/2 (Doyen-Ern-Piperno's spurious oscillations: total variation > 100 over
    [1.1, 1.9]), against < 5 with the redistributed mass."""
    if COMM.size > 1:
        pytest.skip("the transcription is serial")
    NX, dt, steps = 20, 2e-3, 1000
    d = Discretisation(rod1d.problem(COMM, NX=NX), "P1/P1")
    integ = Integrator(d, "newmark", dt=dt)
    U, V = d.initial_state()
    u0, lam = [], []
    for n in range(steps):
        integ.step(U, V, n, n * dt)
        u0.append(U.array[d.cdofs[0]])
        lam.append(integ.lam[0])
    integ.destroy()
    g_u0, g_s = getfem_newmark(NX, dt, steps)
    t = dt * np.arange(1, steps + 1)
    u0, lam = np.array(u0), np.array(lam)
    assert np.abs(u0 - g_u0)[t < 1.0].max() <= 1e-10
    early = t <= 1.05
    assert np.abs(u0 - g_u0)[early].max() <= 1e-7
    assert np.abs(lam - g_s)[early].max() <= 1e-6 * np.abs(g_s[early]).max()
    assert np.count_nonzero(g_s[early] > 0) >= 2                    # two contact events in the window
    phase = (t > 1.1) & (t < 1.9)
    assert np.abs(np.diff(np.array(lam)[phase])).sum() > 100.0
    dr = Discretisation(rod1d.problem(COMM, NX=NX), "P1/P1", "redistributed")
    _, _, _, lam_r = run(dr, "newmark", dt, steps)
    assert np.abs(np.diff(lam_r[phase])).sum() < 5.0
    assert abs(lam_r[phase].mean() - 0.5) < 0.05             # the exact contact stress (measure 1)


@pytest.mark.parametrize("scheme", ["newmark", "central-difference"])
def test_contact_treatment_hook(scheme):
    """contact='penalty' (method/contact): the step solver is the treatment's, its force at the
    contact dof after the step is k (0 - U^{n+1})_+ (k = penalty x the mesh's stiffness per unit
    measure x the measure): Newmark's constrained iterate is U^{n+1}; central differences report
    the force at the state reached (the step used it at U^n); contact_energy is k/2 (0 - U)_+^2;
    the step imposes no constraint (+inf)."""
    if COMM.size > 1:
        pytest.skip("the rod's contact dof on one rank")
    from sdm_dolfinx.contact import penalty
    d = Discretisation(rod1d.problem(COMM, NX=20), "P1/P1", "row-sum")
    k = 2.0 * penalty.stiffness_scale(d) * d.cmeasure[0]
    dt, c = 2e-3, d.cdofs[0]
    integ = Integrator(d, scheme, dt=dt, contact="penalty", contact_options={"penalty": 2.0})
    assert integ.treatment is not None
    U, V = d.initial_state()
    pressed = 0
    for n in range(700):
        info = integ.step(U, V, n, n * dt)
        assert info["gap_imposed"] == np.inf
        pen = max(-U.array[c], 0.0)
        assert integ.lam[0] == pytest.approx(k * pen, rel=1e-9, abs=1e-12 * k)
        assert integ.contact_energy(U) == pytest.approx(0.5 * k * max(-U.array[c], 0.0) ** 2, rel=1e-9, abs=1e-18)
        pressed += pen > 0
    integ.destroy()
    assert pressed > 50


@pytest.mark.parametrize("scheme", ["newmark", "hht"])
def test_body_at_rest_on_the_obstacle_starts_in_equilibrium(scheme):
    """The block starting from its static equilibrium under gravity (frictionless): the initial
    contact force (A U0 - L)_+ at the touching vertices makes a^0 = 0, and the foundation carries
    m g at every step (closed form) to 1e-9; with lam^0 = 0 instead it swung by +-10 % (measured)."""
    from sdm_dolfinx.problems import block
    p = block.problem(COMM)
    d = Discretisation(p, "P2/P1")
    mg = p.rho * 20.0 * 10.0 * 9810.0               # the defaults: 20 x 10 mm, rho, g
    integ = Integrator(d, scheme, dt=1e-4)
    U, V = d.initial_state()
    for n in range(100):
        integ.step(U, V, n, n * 1e-4)
        assert COMM.allreduce(float(np.sum(integ.lam)), op=MPI.SUM) == pytest.approx(mg, rel=1e-9)
    integ.destroy()
