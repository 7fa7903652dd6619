"""Finite strain against what the linear model cannot do: the report's section "Finite strain"
(:mod:`sdm_dolfinx.report.finite_strain_entry`) and the checks of docs/finite_strain.md.

- :func:`spin`: a free square (plane strain, P2/P1, density 1, Lamé (2, 1)) spinning about its centre at
  omega = 2 plus a small deformation rate (:func:`spinning_square`): a hyperelastic material conserves
  the energy and the angular momentum to the Newton tolerance; the linear model's velocity is an
  infinitesimal rotation, so its points move on straight lines and the area grows as 1 + (omega t)^2
  at no elastic energy.
- :func:`rolling`: the disc (R = 20 mm, level 1) started rolling at v = 1000 mm/s with omega R = v on the
  foundation under gravity, Coulomb friction mu = 1, one revolution (2 pi R / v). Measured: the
  centre's advance (the mass's, e^T M U / m, from the momentum) against the rotation angle (the best
  rotation of the displaced dofs about their centroid), the step-by-step energy balance
  E^{n+1} - E^n = lam_N . (U^{n+1} - U^n)_N - (friction's dissipation of the step) and the stick vertices'
  motion. The linear model cannot roll: its contact vertices keep the velocity of an infinitesimal
  rotation, so they are dragged along the plane and friction brakes the disc.
- :func:`ball`: the ball of :mod:`sdm_dolfinx.validation.hertz` at one speed and one material, against
  Hertz's quasi-static t_c, F_max and delta_max.
"""
import time

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.problems import Problem, ball as ball_problem, disc as disc_problem
from sdm_dolfinx.run import simulate
from sdm_dolfinx.validation import hertz

#: the square's Lamé parameters (plane strain), its angular velocity and the spin's time step
LAM, MU, OMEGA, DT = 2.0, 1.0, 2.0, 0.05
#: the rolling disc's speed (mm/s) and Coulomb's coefficient
ROLL_V, ROLL_MU = 1000.0, 1.0
#: the ball's Hertz contact time is resolved by this many steps
BALL_STEPS = 100


def free_body(msh, u0, v0, parts=(), psi=None, lam=LAM, mu=MU, columns=("momentum_x", "momentum_y")):
    """A free plane-strain or 3-D body of density 1 on ``msh``: no load, no contact, Hooke's a(u, w) of
    (lam, mu), which every material linearises to; ``parts``: its Dirichlet parts, ``psi``: its own
    strain energy (``material problem``)."""
    gdim = msh.geometry.dim
    eps = lambda u: ufl.sym(ufl.grad(u))                                                # noqa: E731
    sigma = lambda u: lam * ufl.tr(eps(u)) * ufl.Identity(gdim) + 2 * mu * eps(u)       # noqa: E731
    zero = fem.Constant(msh, np.zeros(gdim, dtype=PETSc.ScalarType))
    return Problem(name="free_body", mesh=msh, shape=(gdim,), a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
                   l=lambda w: ufl.inner(zero, w) * ufl.dx, u0=u0, v0=v0,
                   constraint_vertices=lambda m: np.zeros(0, dtype=np.int32),
                   lower_bound=lambda x: np.zeros(x.shape[1]), constraint_component=1,
                   constraint_measure=lambda q: q * ufl.ds, dirichlet_parts=list(parts), probe=(0.5,) * gdim,
                   extra_columns=columns, momentum_component=1, strain_energy=psi,
                   parameters={"lame_lambda": lam, "lame_mu": mu})


def spinning_square(psi=None, n=4, comm=MPI.COMM_WORLD):
    """The unit square spinning about its centre at OMEGA, plus a small deformation rate, from u0 = 0."""
    msh = dmesh.create_unit_square(comm, n, n)
    v0 = lambda x: np.array([-OMEGA * (x[1] - 0.5) + 0.1 * (x[0] - 0.5) ** 2, OMEGA * (x[0] - 0.5)])  # noqa: E731
    return free_body(msh, lambda x: np.zeros((2, x.shape[1])), v0, psi=psi)


def _dofs(d, U):
    """(initial positions, displaced positions) of this rank's owned dofs of W^h (n x gdim)."""
    gdim = d.problem.mesh.geometry.dim
    n = d.W.dofmap.index_map.size_local
    x = d.W.tabulate_dof_coordinates()[:n, :gdim]
    return x, x + np.asarray(U).reshape(-1, d.W.dofmap.index_map_bs)[:n, :gdim]


def rotation_angle(d, U):
    """The angle of the best rotation (least squares, 2-D) carrying the dofs' initial positions to their
    displaced ones, each about its centroid (collective)."""
    x, y = _dofs(d, U)
    s = d.comm.allreduce(np.r_[x.sum(axis=0), y.sum(axis=0), len(x)], op=MPI.SUM)
    x, y = x - s[:2] / s[4], y - s[2:4] / s[4]
    c = d.comm.allreduce(np.array([np.sum(x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0]), np.sum(x * y)]), op=MPI.SUM)
    return float(np.arctan2(c[0], c[1]))


def outline(d, U, centre):
    """The displaced boundary dofs of a convex 2-D body, ordered by their initial angle about ``centre``,
    closed (rank 0: k x 2; None elsewhere; collective)."""
    msh = d.problem.mesh
    facets = dmesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    dofs = fem.locate_dofs_topological(d.W.sub(0), 1, facets)
    dofs = dofs[dofs < d.W.dofmap.index_map.size_local * d.W.dofmap.index_map_bs] // d.W.dofmap.index_map_bs
    x, y = _dofs(d, U)
    parts = d.comm.gather((x[dofs], y[dofs]), root=0)
    if d.comm.rank != 0:
        return None
    x, y = (np.concatenate([p[k] for p in parts]) for k in (0, 1))
    order = np.argsort(np.arctan2(x[:, 1] - centre[1], x[:, 0] - centre[0]))
    return np.vstack([y[order], y[order[:1]]])


def area(d, U):
    """The deformed area, int det(I + grad u) dx (collective)."""
    u = fem.Function(d.W)
    u.x.array[:len(U)] = U
    u.x.scatter_forward()
    return d.comm.allreduce(fem.assemble_scalar(compat.form(ufl.det(ufl.Identity(2) + ufl.grad(u)) * ufl.dx)),
                            op=MPI.SUM)


def spin(material, revolutions=1.0, comm=MPI.COMM_WORLD):
    """The spinning square with ``material`` for ``revolutions`` turns: its energy and angular momentum
    histories, the area every 4 steps and the outline at half a turn (rank 0: the row; collective)."""
    t0 = time.perf_counter()
    steps = int(round(revolutions * 2 * np.pi / OMEGA / DT))
    half = int(round(np.pi / OMEGA / DT))
    rec = {"area_t": [], "area": [], "outline": None}

    def observe(state):
        if state.n % 4 == 0 or state.n == half:
            rec["area_t"].append(state.t)
            rec["area"].append(area(state.discretisation, state.U))
        if state.n == half:
            rec["outline"] = outline(state.discretisation, state.U, (0.5, 0.5))
    r = simulate(spinning_square(comm=comm), pair="P2/P1", material=material, dt=DT, T=steps * DT, observe=observe)
    ts = r.timeseries
    E = np.asarray(ts["energy"])
    L = np.asarray(ts["angular_momentum"]) if "angular_momentum" in ts else None    # a column of hyperelastic runs
    drift = lambda a, scale: float(np.max(np.abs(a - a[0])) / scale)               # noqa: E731
    return {"material": material, "revolutions": revolutions, "dt": DT, "t": np.asarray(ts["t"]).tolist(),
            "energy": E.tolist(), "elastic": np.asarray(ts["potential"]).tolist(),
            "angular_momentum": None if L is None else L.tolist(),
            "energy_drift": drift(E, E[0]), "angular_drift": None if L is None else drift(L, abs(L[0])),
            "momentum_drift": max(drift(np.asarray(ts[k]), OMEGA / 2) for k in ("momentum_x", "momentum_y")),
            "area_t": rec["area_t"], "area": rec["area"], "half_turn_area": rec["area"][rec["area_t"].index(half * DT)],
            "outline": None if rec["outline"] is None else rec["outline"].tolist(), "its": float(
                np.mean(ts["nonlinear_its"][1:])) if "nonlinear_its" in ts else 0.0,
            "seconds": time.perf_counter() - t0}


class RollingRecord:
    """``simulate``'s observer of the rolling disc: the rotation angle, the normal contact work
    lam . (U^{n+1} - U^n) at the constrained dofs, the active vertices whose tangential dof moved in the
    step, and outlines at ``snapshots`` (steps)."""

    read_only = True

    def __init__(self, snapshots, centre):
        self.theta, self.work, self.moved, self.outlines = [], [0.0], [0], {}
        self.snapshots, self.centre, self.prev = set(snapshots), centre, None

    def __call__(self, state):
        d, comm = state.discretisation, state.discretisation.comm
        self.theta.append(rotation_angle(d, state.U))
        c = d.cdofs
        t = c - d.problem.constraint_component + (1 - d.problem.constraint_component)    # the x dofs
        if self.prev is not None:
            self.work.append(comm.allreduce(float(np.dot(state.lam, state.U[c] - self.prev[c])), op=MPI.SUM))
            moving = (state.lam > 0) & (state.U[t] != self.prev[t])
            self.moved.append(comm.allreduce(int(np.count_nonzero(moving)), op=MPI.SUM))
        self.prev = np.array(state.U)
        if state.n in self.snapshots:
            self.outlines[state.n] = outline(d, state.U, self.centre)


def rolling(material, dt=2e-4, level=1, comm=MPI.COMM_WORLD, snapshots=5):
    """The disc rolling one revolution with ``material`` (see the module); its row (collective)."""
    t0 = time.perf_counter()
    R = 20.0
    steps = int(np.ceil(2 * np.pi * R / ROLL_V / dt - 1e-9))
    rec = RollingRecord(np.linspace(0, steps, snapshots).round().astype(int), (0.0, R))
    params = {"level": level, "height": 0.0, "v0": 0.0, "vx0": ROLL_V, "spin": -ROLL_V / R, "contact_zone": "all"}
    options = {} if material == "linear" else {"newton": "full"}
    r = simulate("disc", params, material=material, friction="coulomb", friction_options={"mu": ROLL_MU}, dt=dt,
                 T=steps * dt, observe=rec, **options)
    ts = r.timeseries
    m = disc_problem.total_mass(r.discretisation.problem)
    p = np.asarray(ts["momentum_x"])
    xc = np.concatenate([[0.0], np.cumsum(0.5 * dt * (p[1:] + p[:-1]))]) / m
    theta = np.unwrap(rec.theta)
    E, diss = np.asarray(ts["energy"]), np.asarray(ts["dissipated"])
    balance = np.diff(E) - np.asarray(rec.work[1:]) + np.diff(diss)
    slips = np.asarray(ts["n_slip"], dtype=int)
    return {"material": material, "dt": dt, "level": level, "steps": steps, "t": np.asarray(ts["t"]).tolist(),
            "xc": xc.tolist(), "theta": theta.tolist(), "energy": E.tolist(), "dissipated": diss.tolist(),
            "normal_work": float(np.sum(rec.work)), "balance": float(np.max(np.abs(balance)) / E[0]),
            "energy_drift": float(np.max(np.abs(E - E[0])) / E[0]),
            "advance_per_revolution": float(xc[-1] / (abs(theta[-1]) / (2 * np.pi)) / (2 * np.pi * R)),
            "advance": float(xc[-1] / (2 * np.pi * R)), "turns": float(abs(theta[-1]) / (2 * np.pi)),
            "moved_unslipping": int(np.max(np.asarray(rec.moved) - slips)), "slip_steps": int(np.count_nonzero(slips)),
            "contact_steps": int(np.count_nonzero(np.asarray(ts["n_active"]))),
            "outlines": {str(k): v.tolist() for k, v in rec.outlines.items() if v is not None},
            "its": float(np.mean(ts["nonlinear_its"][1:])) if "nonlinear_its" in ts else 0.0,
            "seconds": time.perf_counter() - t0}


def ball(material, speed, level=1, comm=MPI.COMM_WORLD):
    """The ball (:mod:`sdm_dolfinx.validation.hertz`) at ``speed`` (mm/s) with ``material`` (newton
    ``initial``) against Hertz, dt = t_c / :data:`BALL_STEPS` (collective)."""
    ref = ball_problem.hertz(v=speed)
    dt = float(f"{ref['t_c'] / BALL_STEPS:.2g}")
    row = hertz.run_one(level, dt, comm=comm, v=speed, material=material,
                        newton=None if material == "linear" else "initial")
    keep = ("level", "dt", "dim_W", "t_c", "F_max", "delta_max", "err_t_c", "err_F_max", "err_delta_max",
            "energy_max_dev", "rebound", "seconds", "hertz")
    return {"material": material, "speed": speed, "delta_over_R": ref["delta_max"] / 20.0,
            **{k: row[k] for k in keep if k in row}}
