"""A restart of a run with gap rows (a curved obstacle; the weighted gap) continues it exactly.

As for the unit rows (test_restart.py): U, V, the active set and the gap-row Newton's cached columns
K^-1 e_j (recorded by their dof's coordinates and component, replayed in their batches) are
restored, so the continued run is bit-identical to the uninterrupted one on 1 rank (RTOL 0). On 2
ranks the parallel factorisation (MUMPS) is not bit-reproducible from run to run: 1e-9 of each
column's scale for the pushed block, as for the unit rows; the sliding disc amplifies those
round-off differences (its contact vertex changes every few steps): two identical uninterrupted
runs in one process differ by up to 2.2e-9 relative (contact_force; measured), the restarted one
by 5e-8, so 1e-6 there. Stopped during contact: the disc in the bowl
(demos/bowl_problem.py, dt = T0/1000, stopped at step 60 of 120) and the P2 block pushed with the
weighted gap (demos/pushed_block_problem.py, stopped at step 40 of 70, the face in contact); the disc
rolling in the bowl with Coulomb friction (mu = 0.5: the frictional solver in each node's frame, its
stick and slip sets and multipliers restored as for the unit rows); the built-in block sliding with
Coulomb friction on the weighted gap (mu = 0.3, v0 = 100 mm/s, stopped at step 40 of 70: the solver on
rows, its face dofs' columns recorded by dof; without its stick/slip state restored the test fails, watched;
without the columns' replay it passes, since that solver's x comes from one more solve per step); a block
dragged by a conveyor belt (friction against a moving obstacle, stopped at step 150 of 300 while it slips);
a bar striking a bar at rest (contact between two bodies: demos/two_bars_problem.py, the rows' facets found
again from U at the restart, stopped at step 60 of 130 during the contact); a block sliding on an elastic
base with Coulomb friction (friction between bodies, demos/sliding_blocks_problem.py coarsened: the rows and
their frames rebuilt from U, the stick/slip sets restored; stopped at step 35 of 120 while it slides; on 2
ranks the restarted and a rerun run both matched the reference exactly, measured: 1e-9 as for the bars).
"""
import json
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.problems import block, load_file
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD
RTOL = {"bowl": 0.0 if COMM.size == 1 else 1e-6, "weighted": 0.0 if COMM.size == 1 else 1e-9,
        "bowl-coulomb": 0.0 if COMM.size == 1 else 1e-6, "weighted-coulomb": 0.0 if COMM.size == 1 else 1e-6,
        "belt-coulomb": 0.0 if COMM.size == 1 else 1e-6, "two-bars": 0.0 if COMM.size == 1 else 1e-9,
        "blocks-coulomb": 0.0 if COMM.size == 1 else 1e-9}
DEMOS = Path(__file__).resolve().parents[2] / "demos"


def _belt():
    """A block (20 x 10 mm, 8 x 4 cells, E = 1000, nu = 0) at rest at its equilibrium on a floor moving
    along x at 100 mm/s."""
    import ufl
    from dolfinx import fem, mesh as dmesh
    from petsc4py import PETSc
    from sdm_dolfinx.obstacles import HalfSpace
    from sdm_dolfinx.problems import Problem
    msh = dmesh.create_rectangle(COMM, [np.zeros(2), np.array([20.0, 10.0])], [8, 4], dmesh.CellType.triangle)
    bottom = lambda x: np.isclose(x[1], 0.0)                                # noqa: E731
    facets = np.sort(dmesh.locate_entities_boundary(msh, 1, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 1, facets, np.ones_like(facets)))(1)
    eps = lambda u: ufl.sym(ufl.grad(u))                                     # noqa: E731
    g = fem.Constant(msh, PETSc.ScalarType((0.0, -9810.0)))
    zero = lambda x: np.zeros((2, x.shape[1]))                               # noqa: E731
    return Problem(name="belt", mesh=msh, shape=(2,), rho=1e-6, u0="equilibrium", v0=zero,
                   a=lambda u, w: 1000.0 * ufl.inner(eps(u), eps(w)) * ufl.dx,
                   l=lambda w: 1e-6 * ufl.inner(g, w) * ufl.dx,
                   constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
                   constraint_component=1, constraint_measure=lambda q: q * ds_c, lower_bound=None,
                   obstacles=[HalfSpace((0.0, 0.0), (0.0, 1.0), motion=lambda t: (100.0 * t, 0.0, 0.0))],
                   extra_columns=("contact_force", "momentum_x"))


def _csv(path):
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.mark.parametrize("case", ["bowl", "weighted", "bowl-coulomb", "weighted-coulomb", "belt-coulomb", "two-bars",
                                  "blocks-coulomb"])
def test_a_run_with_gap_rows_restarts_exactly(case, mpi_tmp_path):
    if case.startswith("bowl"):
        spec = load_file(DEMOS / "bowl_problem.py")
        T0 = spec.problem(COMM).parameters["period"]
        make, kw, stop = (lambda: spec.problem(COMM)), dict(pair="P1+/P0", dt=T0 / 1000, T=120 * T0 / 1000), 60
        if case == "bowl-coulomb":      # friction in each node's frame: the stick/slip sets restored too
            kw.update(friction="coulomb", friction_options={"mu": 0.5})
    elif case == "belt-coulomb":        # friction against a moving obstacle: the slip's reference carried
        make, stop = _belt, 150
        kw = dict(pair="P1+/P0", dt=1e-4, T=0.03, friction="coulomb", friction_options={"mu": 0.3})
    elif case == "weighted-coulomb":    # friction on the weighted gap's rows: its columns by dof, its sets
        make, stop = (lambda: block.problem(COMM, v0=100.0)), 40
        kw = dict(pair="P2/P1", constrain="weighted", dt=1e-4, T=7e-3, friction="coulomb",
                  friction_options={"mu": 0.3})
    elif case == "blocks-coulomb":      # friction between bodies: rows rebuilt per step, the sets restored
        spec = load_file(DEMOS / "sliding_blocks_problem.py")
        make, stop = (lambda: spec.problem(COMM, nx=5, ny=2, base_nx=12, base_ny=2)), 35
        kw = dict(pair="P2/P1", dt=5e-5, T=6e-3, friction="coulomb", friction_options={"mu": 0.3})
    elif case == "two-bars":
        spec = load_file(DEMOS / "two_bars_problem.py")
        make, kw, stop = (lambda: spec.problem(COMM, Nx=20, Ny=2)), dict(pair="P2/P1", dt=5e-7, T=6.5e-5), 60
    else:
        spec = load_file(DEMOS / "pushed_block_problem.py")
        make, kw, stop = (lambda: spec.problem(COMM)), dict(pair="P2/P1", constrain="weighted", dt=1e-4, T=7e-3), 40
    simulate(make(), out=mpi_tmp_path / "ref", **kw)
    with pytest.raises(Exception) as e:
        simulate(make(), out=mpi_tmp_path / "cut", checkpoint_every=7, on_step=lambda n, row: n == stop, **kw)
    assert type(e.value).__name__ == "Interrupted", str(e.value)
    simulate(make(), out=mpi_tmp_path / "cut", checkpoint_every=7, restart=True, **kw)
    if COMM.rank == 0:
        info = json.loads((mpi_tmp_path / "cut" / "run.json").read_text())
        assert info["status"] == "finished"
        a, b = _csv(mpi_tmp_path / "ref" / "timeseries.csv"), _csv(mpi_tmp_path / "cut" / "timeseries.csv")
        header = (mpi_tmp_path / "ref" / "timeseries.csv").read_text().splitlines()[0].split(",")
        force = a[:, header.index("contact_force")]
        assert force[stop - 5:stop + 5].min() > 0                  # stopped in contact
        if case.endswith("coulomb"):                                # vertices stick (bowl), slip (blocks)
            sets = a[:, header.index("n_stick" if case == "bowl-coulomb" else "n_slip")]
            assert sets[:stop].max() > 0 and sets[stop:].max() > 0
        scale = np.maximum(np.abs(a).max(axis=0), 1e-300)
        assert a.shape == b.shape and np.all(np.abs(a - b) <= RTOL[case] * scale)


def test_a_folder_written_before_the_body_field_restarts(mpi_tmp_path, monkeypatch):
    """Run folders of problems with ``bodies`` written before the XDMF's ``body`` field and run.json's
    ``problem.bodies`` existed restart: the bodies' names are not part of the checkpoint's identity, and the
    XDMF goes on without the field its earlier steps lack (the older version's files: made here by leaving
    both out of the interrupted run)."""
    import h5py
    from sdm_dolfinx.io import xdmf_writer
    from sdm_dolfinx.problems.base import Problem
    spec = load_file(DEMOS / "two_bars_problem.py")
    make, kw = (lambda: spec.problem(COMM, Nx=10, Ny=2)), dict(pair="P2/P1", dt=5e-7, T=2e-5)
    out = mpi_tmp_path / "old"
    describe = Problem.describe
    with monkeypatch.context() as older:
        older.setattr(xdmf_writer, "FIELD_ORDER", tuple(f for f in xdmf_writer.FIELD_ORDER if f != "body"))
        older.setattr(Problem, "describe", lambda self: {k: v for k, v in describe(self).items() if k != "bodies"})
        with pytest.raises(Exception) as e:
            simulate(make(), out=out, checkpoint_every=7, on_step=lambda n, row: n == 20, **kw)
    assert type(e.value).__name__ == "Interrupted", str(e.value)
    if COMM.rank == 0:
        assert "bodies" not in json.loads((out / "run.json").read_text())["problem"]
    simulate(make(), out=out, checkpoint_every=7, restart=True, **kw)
    if COMM.rank == 0:
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished" and info["problem"]["bodies"] == ["striker", "struck"]
        with h5py.File(out / "solution.h5", "r") as h5:
            assert "body" not in h5["Function"] and len(h5["Function/displacement"]) == 5
