"""Time schemes (method/schemes): the registry, the update formulas against the schemes'
definitions, and the energy behaviour through the Integrator without constraint.

Definitions (paper eq. (14) for the midpoint scheme; backward Euler as usual), with
Vbar the velocity in W^h:

  midpoint:        M (Vbar^{n+1} - Vbar^n)/dt + A U^{n+1/2} = L,  U^{n+1/2} = (U^n + U^{n+1})/2,
                   (U^{n+1} - U^n)/dt = (Vbar^n + Vbar^{n+1})/2;
  backward Euler:  M (Vbar^{n+1} - Vbar^n)/dt + A U^{n+1} = L,    Vbar^{n+1} = (U^{n+1} - U^n)/dt.

Energy J = 1/2 Vbar^T M Vbar + 1/2 U^T A U - U^T L (Theorem 2): the midpoint scheme keeps
it exactly (J^{n+1} - J^n = (U^{n+1} - U^n)^T [first equation] = 0); backward Euler loses
exactly 1/2 dV^T M dV + 1/2 dU^T A dU per step (a^2 - b^2 = 2 a (a - b) - (a - b)^2).
"""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import schemes
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.schemes import backward_euler, midpoint
from sdm_dolfinx.schemes.base import Scheme
from sdm_dolfinx.problems import membrane

COMM = MPI.COMM_WORLD
#: O(1) random arrays: the update formulas are one or two flops per entry
FLOP_RTOL = 1e-14


# ------------------------------------------------------------------------------ registry
def test_registry_names_and_get():
    assert set(schemes.names()) >= {"midpoint", "backward-euler"}
    assert schemes.get("midpoint") is midpoint.SCHEME
    assert schemes.get("backward-euler") is backward_euler.SCHEME
    for name in schemes.names():
        s = schemes.get(name)
        assert isinstance(s, Scheme) and s.name == name and s.factor > 0 and s.constrained


def test_unknown_scheme():
    with pytest.raises(ValueError) as e:
        schemes.get("verlet")
    msg = str(e.value)
    assert "'verlet'" in msg and "midpoint" in msg and "backward-euler" in msg and "\n" not in msg


def test_register_takes_only_schemes(clean_schemes):
    with pytest.raises(TypeError):
        schemes.register(midpoint.Midpoint)            # the class, not an instance
    with pytest.raises(TypeError):
        schemes.register("midpoint")

    class Forward(Scheme):
        name, factor, constrained = "test-scheme", 1.0, "U^n"
    s = schemes.register(Forward())
    assert schemes.get("test-scheme") is s and "test-scheme" in schemes.names()


def test_register_refuses_a_scheme_without_a_name(clean_schemes):
    """A subclass that forgot ``name`` would be registered under None, and every later message
    listing the schemes (", ".join of the names) would fail."""
    class Nameless(Scheme):
        factor, constrained = 1.0, "U^n"
    with pytest.raises(TypeError, match="a Scheme with a name"):
        schemes.register(Nameless())
    assert None not in schemes.names()


def test_a_scheme_without_factor_must_give_its_coefficients():
    class NoFactor(Scheme):
        name, constrained = "no-factor", "U^n"
    with pytest.raises(NotImplementedError, match="scheme 'no-factor' has no factor: it must define coefficients"):
        NoFactor().coefficients(0.1)


# ------------------------------------------------------------------------------ formulas
@pytest.fixture
def state():
    rng = np.random.default_rng(20100101)
    return {k: rng.standard_normal(50) for k in ("x", "Un", "Vn", "y")}


def close(a, b):
    return np.allclose(a, b, rtol=FLOP_RTOL, atol=FLOP_RTOL * np.abs(b).max())


def test_midpoint_update(state):
    s, dt = midpoint.SCHEME, 0.0125
    x, Un, Vn = state["x"], state["Un"], state["Vn"]
    alpha = s.factor / dt
    assert alpha == 2.0 / dt and s.constrained == "U^{n+1/2}"
    U1 = s.displacement(x, Un)
    assert close((Un + U1) / 2, x)                                   # X is the midpoint
    V1 = s.velocity(x, Un, Vn, alpha)
    assert close(V1, 2 * (U1 - Un) / dt - Vn)
    assert close((Vn + V1) / 2, (U1 - Un) / dt)                      # trapezoidal rule
    # block form: Y = V^{n+1/2} = (V^n + V^{n+1})/2
    assert close((Vn + s.velocity_block(state["y"], Vn)) / 2, state["y"])


def test_backward_euler_update(state):
    s, dt = backward_euler.SCHEME, 0.0125
    x, Un, Vn = state["x"], state["Un"], state["Vn"]
    alpha = s.factor / dt
    assert alpha == 1.0 / dt and s.constrained == "U^{n+1}"
    assert np.array_equal(s.displacement(x, Un), x)
    assert close(s.velocity(x, Un, Vn, alpha), (x - Un) / dt)
    assert np.array_equal(s.velocity_block(state["y"], Vn), state["y"])


@pytest.mark.parametrize("name", ["midpoint", "backward-euler"])
def test_step_matrix_and_update_solve_the_scheme(name):
    """The integrator's linear step (alpha^2 M + A) X = L + M (alpha V^n + alpha^2 U^n) followed
    by the scheme's update satisfies the scheme's defining equations, also for a singular M
    (rank 6 of 12, as the method's M = B^T C^-1 B) -- dense numpy, no PETSc."""
    s = schemes.get(name)
    rng = np.random.default_rng(7)
    n, dt = 12, 0.05
    Bm = rng.standard_normal((6, n))
    M = Bm.T @ Bm                                     # PSD, rank 6
    Q = rng.standard_normal((n, n))
    A = Q @ Q.T + n * np.eye(n)                       # SPD
    L, Un, Vn = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    alpha = s.factor / dt
    X = np.linalg.solve(alpha ** 2 * M + A, L + M @ (alpha * Vn + alpha ** 2 * Un))
    U1, V1 = s.displacement(X, Un), s.velocity(X, Un, Vn, alpha)
    Umid = (Un + U1) / 2 if name == "midpoint" else U1
    residual = M @ (V1 - Vn) / dt + A @ Umid - L
    scale = np.abs(M @ (V1 - Vn) / dt).max() + np.abs(A @ Umid).max() + np.abs(L).max()
    assert np.abs(residual).max() <= 1e-12 * scale
    velocity_def = (Vn + V1) / 2 if name == "midpoint" else V1
    assert np.allclose(velocity_def, (U1 - Un) / dt, rtol=1e-12, atol=1e-12 * np.abs(V1).max())


# ------------------------------------------------------------------------------ energy
def run(name, steps=40, dt=0.01):
    """The membrane without obstacle, N = 4, P1+/P0: energies and increments per step."""
    d = Discretisation(membrane.problem(COMM, N=4, with_obstacle=False), "P1+/P0")
    assert d.num_constraints == 0
    integ = Integrator(d, name, dt=dt)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    energies, losses = [sum(integ.energies(U, V))], []
    for n in range(steps):
        U0, V0 = U.copy(), V.copy()
        info = integ.step(U, V, n, n * dt)
        assert info["n_active"] == 0
        energies.append(sum(integ.energies(U, V)))
        # 1/2 dV^T M dV + 1/2 dU^T A dU, the backward Euler loss
        dU, dV = U - U0, V - V0
        AdU, MdV = dU.duplicate(), dV.duplicate()
        d.A.mult(dU, AdU)
        d.M.mult(dV, MdV)
        losses.append(0.5 * dV.dot(MdV) + 0.5 * dU.dot(AdU))
        for v in (U0, V0, dU, dV, AdU, MdV):
            v.destroy()
    integ.destroy()
    return np.array(energies), np.array(losses)


def test_initial_energy_closed_form():
    # U0 = 0.02 everywhere (A U0 = 0: a constant has no gradient), Vbar0 = 0, L = f (1, phi_i):
    # J(0) = -U0^T L = -0.02 * (-0.6) * |Omega| = 0.012
    E, _ = run("midpoint", steps=0)
    assert abs(E[0] - 0.012) <= 1e-14


def test_midpoint_conserves_energy():
    E, losses = run("midpoint")
    # it moves: the kinetic energy reaches ~40 % of J (a trivially static run would pass too)
    assert losses.max() > 1e-6 * E[0]
    # exact conservation up to round-off: 40 solves with cond(K) ~ 1e2, eps ~ 1e-16
    assert np.abs(E - E[0]).max() <= 1e-12 * abs(E[0])


def test_backward_euler_dissipates_exactly_its_numerical_loss():
    E, losses = run("backward-euler")
    dE = np.diff(E)
    assert np.all(dE <= 1e-14 * abs(E[0]))                  # monotone decrease
    assert E[0] - E[-1] > 1e-3 * E[0]                       # and a real one (first order)
    # J^{n+1} - J^n = -(1/2 dV^T M dV + 1/2 dU^T A dU) to round-off
    assert np.abs(dE + losses).max() <= 1e-12 * abs(E[0])
