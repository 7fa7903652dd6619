"""Prescribed displacements (a Problem's Dirichlet parts, u = u_D(x, t)): lifted exactly, their
reactions and work balance the energy, and the displacement-controlled contact patch test.

Runs on 1 and 2 ranks (every number below is a closed form or an exact identity)."""
import json
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import DirichletPart, Problem, ProblemInputError, simulate
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.problems import load_file

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]
PUSHED = ROOT / "demos" / "pushed_block_problem.py"

#: the shaken bar: length, height, amplitude and angular frequency of the moved end
LENGTH, HEIGHT, AMP, OMEGA = 4.0, 1.0, 0.01, 2.0 * np.pi * 3.0


def shaken_bar(parts=None, components=(0,), nu=0.3):
    """A plane-strain bar [0, 4] x [0, 1] (E = 1, rho = 1), no load, no contact: its left end clamped
    (part ``left``, both components), its right end moved along x by u_D = a sin(w t) (part
    ``right``, its velocity a w cos(w t) given, so that the data's rate at t = 0 is the scheme's)."""
    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([LENGTH, HEIGHT])], [8, 2],
                                 dmesh.CellType.triangle)
    mu, lmbda = 1.0 / (2 * (1 + nu)), nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                        # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)  # noqa: E731
    zero = fem.Constant(msh, np.zeros(2, dtype=PETSc.ScalarType))
    end = lambda x0: (lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[0], x0)))  # noqa: E731
    if parts is None:
        parts = [DirichletPart("left", end(0.0), lambda x, t: 0.0),
                 DirichletPart("right", end(LENGTH), lambda x, t: AMP * np.sin(OMEGA * t),
                               velocity=lambda x, t: AMP * OMEGA * np.cos(OMEGA * t), components=components)]
    return Problem(name="shaken_bar", mesh=msh, shape=(2,), a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
                   l=lambda w: ufl.inner(zero, w) * ufl.dx, u0=lambda x: np.zeros((2, x.shape[1])),
                   v0=lambda x: np.zeros((2, x.shape[1])),
                   constraint_vertices=lambda m: np.zeros(0, dtype=np.int32),
                   lower_bound=lambda x: np.zeros(x.shape[1]), constraint_component=1,
                   constraint_measure=lambda q: q * ufl.ds, dirichlet_parts=parts, probe=(2.0, 0.5),
                   extra_columns=("momentum_x",))


def right_end_x(result):
    """The final u_x at the owned dofs of the right end (x = LENGTH) of W^h."""
    d = result.discretisation
    bs = d.W.dofmap.index_map_bs
    x = d.W.tabulate_dof_coordinates()[:len(result.U.array) // bs]
    blocks = np.flatnonzero(np.isclose(x[:, 0], LENGTH))
    return result.U.array[blocks * bs]


@pytest.mark.parametrize("pair,mass", [("P2/P1", None), ("P1+/P0", None), ("P1/P1", None), ("P2/P1", "consistent")])
def test_midpoint_conserves_energy_minus_dirichlet_work(pair, mass):
    """Midpoint scheme, no contact: with R = K X - b at the Dirichlet rows (the reaction) the step is
    M (V^{n+1} - V^n)/dt + A U^{n+1/2} = L + R at every row, and multiplying by U^{n+1} - U^n =
    dt (V^{n+1} + V^n)/2 gives J^{n+1} - J^n = R . (U^{n+1} - U^n) exactly: J - dirichlet_work is
    constant to round-off (tolerance 1e-11 of the energy scale, max |J|; measured 1e-14). The
    iterate's value (U^n + u_D(t_{n+1}))/2 at the moved end makes U^{n+1} = u_D(t_{n+1}) there to
    round-off. Momentum: e_x^T A = 0 and L = 0, so e_x^T M (V^{n+1} - V^n)/dt is the sum of the
    x reactions of both parts, exactly (tolerance 1e-10 of the largest reaction)."""
    dt, T = 0.01, 1.0
    r = simulate(shaken_bar(), pair=pair, mass=mass, dt=dt, T=T)
    ts = r.timeseries
    assert {"reaction_left_x", "reaction_left_y", "reaction_right_x", "dirichlet_work"} <= set(ts)
    assert "reaction_right_y" not in ts                 # only the prescribed component has a reaction
    scale = np.abs(ts["energy"]).max()
    assert scale > 1e-3                                 # the moved end put energy in
    balance = ts["energy"] - ts["dirichlet_work"]
    assert np.abs(balance - balance[0]).max() <= 1e-11 * scale
    end = right_end_x(r)
    assert np.allclose(end, AMP * np.sin(OMEGA * T), rtol=0, atol=1e-14)
    assert COMM.allreduce(len(end), op=MPI.SUM) == (5 if pair.startswith("P2") else 3)     # the end x = 4 of 2 cells
    forces = ts["reaction_left_x"] + ts["reaction_right_x"]
    assert np.abs(np.diff(ts["momentum_x"]) / dt - forces[1:]).max() <= 1e-10 * np.abs(forces).max()


def test_backward_euler_dissipates_energy_minus_dirichlet_work():
    """Backward Euler: the same computation with U^{n+1} - U^n = dt V^{n+1} gives J^{n+1} - J^n +
    1/2 |V^{n+1} - V^n|_M^2 + 1/2 |U^{n+1} - U^n|_A^2 = R . (U^{n+1} - U^n): J - dirichlet_work never
    increases (up to round-off, 1e-12 of the energy scale), and here decreases by a visible part."""
    r = simulate(shaken_bar(), pair="P2/P1", scheme="backward-euler", dt=0.01, T=1.0)
    ts = r.timeseries
    balance = ts["energy"] - ts["dirichlet_work"]
    scale = np.abs(ts["dirichlet_work"]).max()
    assert np.diff(balance).max() <= 1e-12 * scale
    assert balance[-1] - balance[0] < -0.1 * scale
    assert np.allclose(right_end_x(r), AMP * np.sin(OMEGA * 1.0), rtol=0, atol=1e-14)


def _hold_mean(ts, ramp=5e-3):
    hold = ts["t"] > ramp * (1 + 1e-9)
    return ts["contact_force"][hold].mean(), -ts["reaction_top_y"][hold].mean()


@pytest.mark.parametrize("pair,constrain,nu", [("P1+/P0", "vertices", 0.0), ("P2/P1", "nodes", 0.0),
                                               ("P1+/P0", "vertices", 0.3), ("P2/P1", "nodes", 0.3)])
def test_contact_patch_test_with_prescribed_displacement(pair, constrain, nu):
    """The block on the frictionless foundation pushed by its top (demos/pushed_block_problem.py, whose
    docstring derives F = E/(1 - nu^2) width d / height, plane strain with free lateral expansion:
    20 x 10 mm, E = 1000, d = 10 um, F = 20 N/mm at nu = 0): the foundation's force (contact_force)
    and the punch's (-reaction_top_y), averaged over the hold after a ramp slow against the block's
    vibrations (omega_1 ramp = 50), are F within 0.5 % (measured within 7e-5) on the pairs whose
    contact face holds the linear solution (constraint at every boundary dof of W^h)."""
    r = simulate(str(PUSHED), {"nu": nu}, pair=pair, constrain=constrain)       # dt 1e-4, T 10 ms: 100 steps
    F = load_file(PUSHED).problem(nu=nu).parameters["force"]
    assert F == pytest.approx(20.0 / (1 - nu * nu), rel=1e-14)
    contact, punch = _hold_mean(r.timeseries)
    assert contact == pytest.approx(F, rel=5e-3)
    assert punch == pytest.approx(F, rel=5e-3)


def test_p2_vertex_constraint_sinks_between_vertices():
    """The same push with P2/P1 and the constraint at the vertices only (eq. (13), the default): the
    uniform pressure needs forces at the mid-edge nodes, which the vertex multipliers cannot give,
    so the contact face sinks between the vertices and the block is too soft. Measured (8 x 4
    squares): the reaction is 10.2 % below F and the mid-edge nodes 1.62 um below the foundation,
    16 % of the 10 um push (asserted: more than 8 % and 12 %). A known defect of that pair and
    constraint, not hidden: --constrain nodes removes it (the test above)."""
    r = simulate(str(PUSHED), {}, pair="P2/P1", constrain="vertices")
    contact, punch = _hold_mean(r.timeseries)
    assert 0.08 < 1 - contact / 20.0 < 0.12 and 0.08 < 1 - punch / 20.0 < 0.12
    assert r.timeseries["gap_min_boundary"][-1] < -0.12 * 0.01


def test_pushed_block_restart_continues_exactly(mpi_tmp_path):
    """Interrupted at step 37 (during the ramp, in contact) and restarted from its checkpoint: the
    time series (reactions and dirichlet_work included, the latter continued from the CSV) is the
    uninterrupted run's, bit for bit on 1 rank (1e-9 on 2: the new partition sums in another
    order, as tests/integration/test_restart.py allows)."""
    rtol = 0.0 if COMM.size == 1 else 1e-9
    kw = dict(pair="P1+/P0", T=6e-3)
    simulate(str(PUSHED), {}, out=mpi_tmp_path / "ref", **kw)
    with pytest.raises(Exception) as e:
        simulate(str(PUSHED), {}, out=mpi_tmp_path / "cut", checkpoint_every=7,
                 on_step=lambda n, row: n == 37, **kw)
    assert type(e.value).__name__ == "Interrupted"
    simulate(str(PUSHED), {}, out=mpi_tmp_path / "cut", restart=True, checkpoint_every=7, **kw)
    if COMM.rank == 0:
        a, b = (np.loadtxt(mpi_tmp_path / f / "timeseries.csv", delimiter=",", skiprows=1) for f in ("ref", "cut"))
        header = (mpi_tmp_path / "ref" / "timeseries.csv").read_text().splitlines()[0].split(",")
        assert header[-2:] == ["reaction_top_y", "dirichlet_work"]
        assert a.shape == b.shape == (61, len(header))
        assert np.allclose(a, b, rtol=rtol, atol=rtol * np.abs(a).max(axis=0))
        info = json.loads((mpi_tmp_path / "cut" / "run.json").read_text())
        assert info["problem"]["dirichlet_parts"] == [{"name": "top", "components": [1]}]


@pytest.mark.parametrize("options,message", [
    (dict(scheme="newmark"), "scheme 'newmark' does not take Dirichlet parts"),
    (dict(scheme="hht"), "scheme 'hht' does not take Dirichlet parts"),
    (dict(contact="nitsche"), "contact 'nitsche' with Dirichlet parts is not supported"),
])
def test_schemes_and_treatments_without_moving_data_refuse_parts(options, message):
    """What does not lift the data consistently refuses a Problem with Dirichlet parts in one line."""
    with pytest.raises(DiscretisationError, match=message):
        simulate(str(PUSHED), {}, T=2e-4, **options)


def test_penalty_and_friction_take_parts():
    """The penalty treatment and friction act at the contact dofs only, which no part prescribes: the
    push runs, and the foundation carries the punch's force on average (within 2 %: the penalty's
    springs and the stick/slip add their own small dynamics)."""
    for options in (dict(contact="penalty", contact_options={"penalty": 100.0}),
                    dict(friction="coulomb", friction_options={"mu": 0.3})):
        contact, punch = _hold_mean(simulate(str(PUSHED), {}, **options).timeseries)
        assert punch == pytest.approx(20.0, rel=2e-2) and contact == pytest.approx(punch, rel=2e-2)


def test_bad_parts_are_refused_in_one_line():
    """Overlapping parts, components a vector u does not have, twice the same name, data of the wrong
    shape: each refused in one line naming the part."""
    left = lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[0], 0.0))   # noqa: E731
    with pytest.raises(DiscretisationError, match="part 'b' shares prescribed dofs with part 'a'"):
        simulate(shaken_bar([DirichletPart("a", left, lambda x, t: 0.0),
                             DirichletPart("b", left, lambda x, t: t, components=(1,))]), dt=0.01, T=0.02)
    simulate(shaken_bar([DirichletPart("a", left, lambda x, t: 0.0, components=(0,)),     # disjoint components
                         DirichletPart("b", left, lambda x, t: 0.0, components=(1,))]), dt=0.01, T=0.02)
    legacy = shaken_bar()
    legacy.dirichlet_facets, legacy.dirichlet_value = left, lambda x: np.zeros((2, x.shape[1]))
    with pytest.raises(DiscretisationError, match="part 'left' shares prescribed dofs with dirichlet_facets"):
        simulate(legacy, dt=0.01, T=0.02)
    with pytest.raises(ProblemInputError, match="part 'a': components must be distinct integers in 0..1"):
        shaken_bar([DirichletPart("a", left, lambda x, t: 0.0, components=(2,))])
    with pytest.raises(ProblemInputError, match=r"components must be .* \(got 1\)"):
        shaken_bar([DirichletPart("a", left, lambda x, t: 0.0, components=1)])
    with pytest.raises(ProblemInputError, match="must be a distinct identifier"):
        shaken_bar([DirichletPart("a", left, lambda x, t: 0.0), DirichletPart("a", left, lambda x, t: 0.0)])
    with pytest.raises(DiscretisationError, match=r"part 'a': value\(x, t\) returned shape \(3,"):
        simulate(shaken_bar([DirichletPart("a", left, lambda x, t: np.zeros((3, x.shape[1])))]), dt=0.01, T=0.02)


def test_parts_that_would_give_a_wrong_run_are_refused_in_one_line():
    """Inputs a new user wrote that ran and gave a plausible wrong run: a part on the contact face
    (it switched the contact off there, the face pushed below the foundation), facets(mesh) that
    matched nothing (the punch never moved) or returned vertex indices (arbitrary facets moved), a
    sine pushed without ``velocity`` (energy off by half: the part's velocity alternates), value(x)
    for value(x, t) (an internal error), and u0 = None (an internal error). Each is now refused in
    one line naming the part; the same sine with its velocity, and data starting at rest without
    one (1 - cos), run."""
    left = lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[0], 0.0))   # noqa: E731
    right = lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[0], LENGTH))   # noqa: E731
    clamp = DirichletPart("left", left, lambda x, t: 0.0)
    block = load_file(str(PUSHED)).problem()
    bottom = lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[1], 0.0))   # noqa: E731
    block.dirichlet_parts = [DirichletPart("bottom", bottom, lambda x, t: -1e-3 * t, components=(1,))]
    with pytest.raises(DiscretisationError, match=r"part 'bottom' prescribes the constrained component at \d+ "
                                                  r"constrained points, where it would switch the contact off"):
        simulate(block, dt=1e-4, T=2e-4)
    block.dirichlet_parts = [DirichletPart("bottom", bottom, lambda x, t: 0.0, components=(0,))]   # tangential: fine
    simulate(block, dt=1e-4, T=2e-4)
    nothing = lambda m: dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[0], -1.0))   # noqa: E731
    with pytest.raises(DiscretisationError, match="part 'top': facets.mesh. returned no facet on any rank"):
        simulate(shaken_bar([clamp, DirichletPart("top", nothing, lambda x, t: 0.0)]), dt=0.01, T=0.02)
    vertices = lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: np.isclose(x[0], LENGTH))   # noqa: E731
    with pytest.raises(DiscretisationError, match=r"part 'right': \d+ of the \d+ indices .* are not boundary facets"):
        simulate(shaken_bar([clamp, DirichletPart("right", vertices, lambda x, t: 0.0)]), dt=0.01, T=0.02)
    sine = lambda x, t: AMP * np.sin(OMEGA * t)     # noqa: E731
    with pytest.raises(DiscretisationError, match=r"part 'right': its data move at t = 0 .* velocity\(x, 0\) is not "
                                                  r"given"):
        simulate(shaken_bar([clamp, DirichletPart("right", right, sine, components=(0,))]), dt=0.01, T=0.02)
    with pytest.raises(DiscretisationError, match=r"velocity\(x, 0\) is up to 0.0942"):     # half the rate
        simulate(shaken_bar([clamp, DirichletPart("right", right, sine, components=(0,),
                                                  velocity=lambda x, t: 0.5 * AMP * OMEGA)]), dt=0.01, T=0.02)
    simulate(shaken_bar([clamp, DirichletPart("right", right, lambda x, t: AMP * (1 - np.cos(OMEGA * t)),
                                              components=(0,))]), dt=0.01, T=0.02)
    with pytest.raises(DiscretisationError, match=r"part 'right': value\(x, t\) failed .* takes the points x"):
        simulate(shaken_bar([clamp, DirichletPart("right", right, lambda x: 0.0)]), dt=0.01, T=0.02)
    with pytest.raises(ProblemInputError, match="u0 must be x -> values, a dolfinx Function or 'equilibrium'"):
        bar = shaken_bar()
        Problem(**{**{f: getattr(bar, f) for f in ("name", "mesh", "shape", "a", "l", "v0", "constraint_vertices",
                                                    "lower_bound", "constraint_component", "constraint_measure")},
                   "u0": None})


@pytest.mark.skipif(COMM.size > 1, reason="serial: the command runs in a process of its own")
def test_command_line_runs_the_problem_file_and_refuses_newmark(tmp_path):
    """From the command line and a TOML configuration: the reaction columns in timeseries.csv; a
    scheme without Dirichlet parts is refused in one line with exit status 2."""
    cmd = [sys.executable, "-m", "sdm_dolfinx", "run", "--problem-file", str(PUSHED), "--T", "1e-3"]
    p = subprocess.run(cmd + ["--out", str(tmp_path / "a"), "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    header = (tmp_path / "a" / "timeseries.csv").read_text().splitlines()[0]
    assert header.endswith(",reaction_top_y,dirichlet_work")
    p = subprocess.run(cmd + ["--scheme", "newmark", "--out", str(tmp_path / "b")], capture_output=True, text=True)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "does not take Dirichlet parts" in p.stderr
    (tmp_path / "c.toml").write_text(f'problem-file = "{PUSHED}"\nT = 1e-3\nnu = 0.3\n')
    p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "run", "--config", str(tmp_path / "c.toml"), "--out",
                        str(tmp_path / "c"), "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "c" / "timeseries.csv").read_text().splitlines()[0] == header


def test_scalar_unknown_has_one_reaction_column_per_part():
    """A scalar u (a 1-D bar, E = rho = 1, P2/P1): the parts' columns are reaction_<name>; the data
    may be a number or an (n,) array; the midpoint scheme conserves J - dirichlet_work (1e-11 of
    the energy scale) and momentum e^T M V changes by the sum of the reactions (1e-10)."""
    msh = dmesh.create_interval(COMM, 10, [0.0, 1.0])
    zero = fem.Constant(msh, PETSc.ScalarType(0.0))
    end = lambda x0: (lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: np.isclose(x[0], x0)))  # noqa: E731
    p = Problem(name="bar1d", mesh=msh, shape=(), a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
                l=lambda w: zero * w * ufl.dx, u0=lambda x: np.zeros(x.shape[1]), v0=lambda x: np.zeros(x.shape[1]),
                constraint_vertices=lambda m: np.zeros(0, dtype=np.int32), lower_bound=lambda x: np.zeros(x.shape[1]),
                constraint_measure=lambda q: q * ufl.ds, probe=(0.5, 0.0), extra_columns=("momentum_x",),
                dirichlet_parts=[DirichletPart("left", end(0.0), lambda x, t: 0.1 * (1 - np.cos(5 * t)) + 0 * x[0]),
                                 DirichletPart("right", end(1.0), lambda x, t: 0.0)])
    dt = 0.02
    ts = simulate(p, pair="P2/P1", dt=dt, T=2.0).timeseries
    assert [c for c in ts if c.startswith("reaction")] == ["reaction_left", "reaction_right"]
    balance, scale = ts["energy"] - ts["dirichlet_work"], np.abs(ts["energy"]).max()
    assert scale > 1e-3 and np.abs(balance - balance[0]).max() <= 1e-11 * scale
    forces = ts["reaction_left"] + ts["reaction_right"]
    assert np.abs(np.diff(ts["momentum_x"]) / dt - forces[1:]).max() <= 1e-10 * np.abs(forces).max()
