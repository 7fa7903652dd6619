"""Friction in the singular dynamic method: identities that hold at every step, on a
plane-strain block sliding on the foundation y = 0 (1 and 2 ranks).

* the discrete Coulomb cone |lam_T,i| <= mu lam_N,i (Tresca: <= s m_i) at every vertex, stick
  vertices without slip, slip vertices with a full-size lam_T opposing their slip;
* the horizontal momentum balance P^{n+1} - P^n = dt (F_x + sum lam_T) exactly (the midpoint
  scheme with a rigid e_x: eT A = 0, see contact/friction.py);
* energy: E^{n+1} - E^n = lam . (U^{n+1} - U^n) (midpoint), whose tangential part is the
  friction work <= 0: with the bottom resting on the foundation the normal part vanishes and
  E + dissipated is conserved to round-off;
* mu = 0 is the frictionless run to round-off; friction options that do not agree are refused.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.contact.friction import make
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.problems import Problem
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD
G = 9810.0
RHO = 1e-6


def resting_block(width=20.0, height=10.0, n=10, E=1000.0, nu=0.3, v0=100.0, g=(0.0, -G), comm=COMM,
                  equilibrium=True):
    """A block on the foundation y = 0 sliding at v0 along x, its bottom there: at rest under
    gravity with u_y = 0 at the bottom vertices (``equilibrium``: the P2 static solution, so the
    contact does not oscillate), or unstressed."""
    msh = dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([width, height])],
                                 [n, max(1, round(n * height / width))], dmesh.CellType.triangle)
    fdim = msh.topology.dim - 1
    bottom = lambda x: np.isclose(x[1], 0.0)
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)
    gv = fem.Constant(msh, PETSc.ScalarType(g))
    u0 = _static(msh, sigma, eps, gv, bottom) if equilibrium else (lambda x: np.zeros((2, x.shape[1])))
    return Problem(
        name="resting_block", mesh=msh, shape=(2,), rho=RHO,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: RHO * ufl.inner(gv, w) * ufl.dx,
        u0=u0, v0=lambda x: np.vstack([np.full(x.shape[1], v0), np.zeros(x.shape[1])]),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
        lower_bound=lambda x: np.zeros(x.shape[1]), constraint_component=1,
        constraint_measure=lambda q: q * ds_c, probe=(width / 2, 0.0),
        extra_columns=("contact_force", "momentum_x", "momentum_y"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu})


def _static(msh, sigma, eps, gv, bottom):
    """The P2 static displacement under gravity with u_y = 0 at the bottom vertices (the run's
    constraint, bilateral) and u_x = 0 at the bottom-left vertex (the rigid translation)."""
    from sdm_dolfinx import compat
    V = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 2, (2,)))
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    verts = dmesh.locate_entities_boundary(msh, 0, bottom)
    corner = dmesh.locate_entities_boundary(msh, 0, lambda x: np.isclose(x[0], 0.0) & np.isclose(x[1], 0.0))
    zero = PETSc.ScalarType(0.0)
    bcs = [fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(1), 0, verts), V.sub(1)),
           fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(0), 0, corner), V.sub(0))]
    return compat.solve_linear_problem(ufl.inner(sigma(u), eps(w)) * ufl.dx, RHO * ufl.inner(gv, w) * ufl.dx, bcs,
                                       {"ksp_type": "preonly", "pc_type": "lu"}, "sdm_test_static_")


def _steps(problem, friction, pair="P2/P1", scheme="midpoint", dt=2e-5, n=60):
    """Step an Integrator by hand; per step the solver's sets and multipliers, checked by the caller."""
    d = Discretisation(problem, pair)
    integ = Integrator(d, scheme, dt, friction=friction)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    for k in range(n):
        Un = U.array.copy()
        info = integ.step(U, V, k, k * dt)
        yield d, integ, info, U.array - Un
    integ.destroy()


@pytest.mark.parametrize("law", ["coulomb", "tresca"])
def test_cone_stick_and_slip_at_every_step(law):
    """Every step: |lam_T| <= bound (1e-9 relative to the largest multiplier), stick => no slip
    (1e-9 of the step's largest slip), slip => lam_T = -bound sign(slip) (1e-9)."""
    mu, s = 0.3, 0.03
    f = make(law, mu=mu if law == "coulomb" else None, threshold=s if law == "tresca" else None)
    worst = np.zeros(3)
    n_slip = 0
    for d, integ, info, du in _steps(resting_block(), f):
        solver = integ.solver
        lam_n, lam_t, slip = solver.lam, solver.lam_t, du[integ.tdofs]
        bound = mu * lam_n if law == "coulomb" else s * d.cmeasure
        scale = max(COMM.allreduce(float(np.abs(np.r_[lam_n, lam_t, 1e-300]).max()), op=MPI.MAX), 1e-300)
        dscale = max(COMM.allreduce(float(np.abs(np.r_[slip, 0.0]).max()), op=MPI.MAX), 1e-300)
        st, sl = solver.stick & solver.active if law == "coulomb" else solver.stick, solver.slip
        worst = np.maximum(worst, [np.max(np.abs(lam_t) - bound, initial=0.0) / scale,
                                   np.max(np.abs(slip[st]), initial=0.0) / dscale,
                                   np.max(np.abs(lam_t[sl] + bound[sl] * np.sign(slip[sl])), initial=0.0) / scale])
        n_slip += info["n_slip"]
    COMM.Allreduce(MPI.IN_PLACE, worst, op=MPI.MAX)
    assert np.all(worst < 1e-9), worst
    assert n_slip > 0                                # the block slides: the slip branch is tested


@pytest.mark.parametrize("law", ["coulomb", "tresca"])
def test_momentum_and_energy_balance(law):
    """Midpoint, the block resting on the floor and sliding: P_x^{n+1} - P_x^n = dt sum lam_T
    (no horizontal load) to 1e-10 of |P_x|; E^{n+1} - E^n = friction work <= 0 while every bottom
    vertex has stayed in contact (the first 19 to 30 steps here; then the rear corner lifts off for a
    while), and E + dissipated is conserved to 1e-12 of E^0 (measured: 5e-14)."""
    f = make(law, mu=0.3 if law == "coulomb" else None, threshold=0.03 if law == "tresca" else None)
    dt, n = 2e-5, 60
    r = simulate(resting_block(), pair="P2/P1", dt=dt, T=n * dt, friction=law,
                 friction_options={"mu": f.mu, "tresca_threshold": f.threshold})
    ts = r.timeseries
    px = ts["momentum_x"]
    assert np.abs(np.diff(px) - dt * ts["tangential_force"][1:]).max() < 1e-10 * np.abs(px).max()
    assert px[-1] < px[0] and np.all(np.diff(ts["dissipated"]) >= -1e-15 * ts["energy"][0])
    # sustained contact: every bottom vertex in contact at every step so far (a vertex that
    # leaves and comes back carries U^n_n != bound, and the normal contact does work after it)
    sustained = np.cumprod(ts["n_active"][1:] == r.info["N_g"]).astype(bool)
    assert sustained.sum() >= 15
    total = ts["energy"] + ts["dissipated"]
    jumps = np.abs(np.diff(total))[sustained] / ts["energy"][0]
    assert jumps.max() < 1e-12, jumps.max()
    assert ts["dissipated"][-1] > 1e-3 * ts["energy"][0]          # friction did dissipate


def test_zero_friction_coefficient_is_the_frictionless_run():
    dt, n = 2e-5, 40
    a = simulate(resting_block(), pair="P2/P1", dt=dt, T=n * dt)
    b = simulate(resting_block(), pair="P2/P1", dt=dt, T=n * dt, friction="coulomb", friction_options={"mu": 0.0})
    p = np.abs(a.timeseries["momentum_x"]).max()            # momentum_y is ~0: the momentum scale
    for c in ("energy", "u_probe", "contact_force", "momentum_x", "momentum_y"):
        scale = p if c.startswith("momentum") else max(np.abs(a.timeseries[c]).max(), 1e-300)
        assert np.abs(a.timeseries[c] - b.timeseries[c]).max() < 1e-10 * scale, c
    assert np.all(b.timeseries["tangential_force"] == 0.0)


@pytest.mark.parametrize("opts, message", [
    ({"friction": "coulomb"}, "friction coulomb needs mu"),
    ({"friction": "tresca", "friction_options": {"mu": 0.3}}, "mu is a parameter of friction coulomb, not of friction "
                                                              "tresca"),
    ({"friction": "coulomb", "friction_options": {"mu": -1.0}}, "mu must be a number >= 0"),
    ({"friction": "stiction", "friction_options": {"mu": 0.3}}, "unknown friction law"),
    ({"friction": "coulomb", "friction_options": {"mu": 0.3}, "linear": "amg"}, "not vi_solver ssn with linear amg"),
    ({"friction": "tresca", "friction_options": {"tresca_threshold": 0.1}, "vi_solver": "vinewtonrsls"},
     "not vi_solver vinewtonrsls"),
])
def test_friction_options_that_do_not_agree_are_refused(opts, message):
    """Also a step solver friction has not: the option would otherwise be ignored."""
    with pytest.raises((ValueError, DiscretisationError), match=message):
        simulate(resting_block(n=2), pair="P2/P1", dt=1e-5, T=1e-5, **opts)


@pytest.mark.mpi
@pytest.mark.parametrize("law", ["coulomb", "tresca"])
def test_one_and_all_ranks_agree(law):
    """The run on every rank (COMM_WORLD) against the same run on each rank alone (COMM_SELF): the
    time series agree to 1e-9 of each column's scale (2 ranks: the partition changes only the
    rounding; 1 rank: identical)."""
    kw = {"friction_options": {"mu": 0.3} if law == "coulomb" else {"tresca_threshold": 0.03}}
    dt, n = 2e-5, 40
    ref = simulate(resting_block(comm=MPI.COMM_SELF), pair="P2/P1", dt=dt, T=n * dt, friction=law, **kw)
    run = simulate(resting_block(), pair="P2/P1", dt=dt, T=n * dt, friction=law, **kw)
    for c in ("energy", "contact_force", "tangential_force", "momentum_x", "dissipated", "slip_probe", "n_slip"):
        a, b = ref.timeseries[c], run.timeseries[c]
        assert np.abs(a - b).max() <= 1e-9 * max(np.abs(a).max(), 1e-300), c


def test_interrupted_frictional_run_restarts_to_the_same_results(mpi_tmp_path):
    """A Coulomb run stopped at step 35 (checkpoint) and restarted equals the uninterrupted run in
    every physical column to 1e-12 of its scale (serially bit for bit, tests/integration/test_restart.py),
    and in its Newton iteration counts (the solver's sets are restored, not started afresh)."""
    from sdm_dolfinx.run.signals import Interrupted
    dt, n = 2e-5, 60
    kw = dict(pair="P2/P1", dt=dt, T=n * dt, friction="coulomb", friction_options={"mu": 0.3})
    ref = simulate(resting_block(), **kw)
    out = mpi_tmp_path / "cut"
    with pytest.raises(Interrupted):
        simulate(resting_block(), out=out, checkpoint_every=10, on_step=lambda k, row: k == 35, **kw)
    r = simulate(resting_block(), out=out, restart=True, **kw)
    assert r.info["restarted_from_step"] == 35
    for c in ("energy", "momentum_x", "contact_force", "tangential_force", "dissipated", "slip_probe", "n_slip",
              "newton_its"):
        a, b = ref.timeseries[c], r.timeseries[c]
        assert np.abs(a - b).max() <= 1e-12 * max(np.abs(a).max(), 1e-300), c


@pytest.mark.parametrize("scheme", ["midpoint", "backward-euler"])
def test_both_schemes_balance_momentum_in_both_directions(scheme):
    """P^{n+1} - P^n = dt (loads + sum of multipliers) along x (sum lam_T) and y (sum lam_N -
    m g) exactly for either scheme (e^T A = 0 for a rigid e), to 1e-10 of |P|; backward Euler
    also only loses energy: E + dissipated never increases in sustained contact (1e-12 E^0)."""
    dt, n = 2e-5, 40
    r = simulate(resting_block(), pair="P2/P1", scheme=scheme, dt=dt, T=n * dt, friction="coulomb",
                 friction_options={"mu": 0.3})
    ts = r.timeseries
    m = RHO * 20.0 * 10.0
    scale = np.abs(ts["momentum_x"]).max()
    assert np.abs(np.diff(ts["momentum_x"]) - dt * ts["tangential_force"][1:]).max() < 1e-10 * scale
    assert np.abs(np.diff(ts["momentum_y"]) - dt * (ts["contact_force"][1:] - m * G)).max() < 1e-10 * scale
    assert ts["n_slip"][1:].min() > 0
    if scheme == "backward-euler":
        sustained = np.cumprod(ts["n_active"][1:] == r.info["N_g"]).astype(bool)
        total = ts["energy"] + ts["dissipated"]
        assert sustained.sum() >= 15 and np.diff(total)[sustained].max() < 1e-12 * ts["energy"][0]


def test_xdmf_contact_status_and_tangential_stress(mpi_tmp_path):
    """The file's contact_status at the vertices counts the step's slipping and sticking vertices
    (n_slip; n_active - n_slip), and tangential_stress is nonzero exactly where they are in
    contact (Coulomb: no friction off contact)."""
    dt, n = 2e-5, 20
    out = mpi_tmp_path / "xdmf"
    r = simulate(resting_block(), pair="P2/P1", dt=dt, T=n * dt, friction="coulomb", friction_options={"mu": 0.3},
                 out=out, write_every=n)
    res = None
    if COMM.rank == 0:
        from sdm_dolfinx.io.xdmf_reader import read_xdmf
        s = read_xdmf(out)
        bottom = s.vertex_mask() & np.isclose(s.points[:, 1], 0.0)
        raw = s.field("contact_status", n * dt)[bottom]
        stress = s.field("tangential_stress", n * dt)[bottom]
        # The codes pass through the P2 output space: at a vertex they are the code to round-off
        # (OpenBLAS leaves ~1e-16 in the P2 nodes' coordinates); 1e-9 is far below the gap of 1.
        status = np.rint(raw)
        res = (sorted(s.fields), int(np.sum(status == 2)), int(np.sum(status == 1)),
               bool(np.all((np.abs(stress) > 1e-9 * np.abs(stress).max()) == (status > 0))),
               bool(np.all(np.isin(status, (0.0, 1.0, 2.0)) & (np.abs(raw - status) < 1e-9))))
    fields, slipping, sticking, where, codes = COMM.bcast(res, root=0)
    assert "contact_status" in fields and "tangential_stress" in fields and codes and where
    assert slipping == r.timeseries["n_slip"][-1] > 0
    assert sticking == r.timeseries["n_active"][-1] - r.timeseries["n_slip"][-1]


@pytest.mark.skipif(COMM.size > 1, reason="the command line prints on rank 0 only: checked on 1 rank")
def test_command_line_refuses_a_linear_strategy_friction_has_not(tmp_path, capsys):
    """One line, exit 2, nothing written: --linear amg would otherwise be ignored."""
    from sdm_dolfinx.cli import main
    out = tmp_path / "run"
    assert main(["block", "--friction", "coulomb", "--mu", "0.3", "--linear", "amg", "--T", "1e-3",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "not vi_solver ssn with linear amg" in err and err.count("\n") == 1 and not out.exists()
