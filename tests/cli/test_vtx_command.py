"""``python -m sdm_dolfinx vtx DIR``: a run's fields as VTX files where dolfinx has ADIOS2, refused in
one line where it has none.

Where it has ADIOS2 (PyPI's wheel, ``make test-dolfinx011``) the files are read back by ADIOS2's own
Python bindings (PyPI's ``adios2``, in a process of its own: imported beside the wheel's dolfinx it
loads another ADIOS2) and checked against what the run wrote independently: the displacement against
``state.h5``'s dof vectors at the same points, the velocity through the kinetic energy of
``timeseries.csv``.
"""
import json
import subprocess
import sys

from mpi4py import MPI

import numpy as np
import pytest
import ufl

from sdm_dolfinx import cli, compat

pytestmark = pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")   # P2's sink
COMM = MPI.COMM_WORLD
HAS_VTX = compat.has_vtx()

#: reads every step of a VTX file to stdout as JSON: {"t": [...], "points": [...], "values": [...]}, argv[3] saying
#: whether the field is given per point or per cell. Each rank wrote a block with its ghosts: points are told
#: apart by their original (global) ids, cells by their vertices' ids; a point or cell in two blocks must carry
#: the same value in both
READER = """
import json, sys
import numpy as np
from adios2 import Stream
path, name, kind = sys.argv[1:4]
out = {"t": [], "points": [], "values": []}
with Stream(path, "r") as s:
    for _ in s.steps():
        blocks = range(len(s.engine.blocks_info("geometry", s.current_step())))
        read = lambda var, b: np.asarray(s.read(var, block_id=b))
        seen = {}
        for b in blocks:
            x, ids, v = read("geometry", b), read("vtkOriginalPointIds", b).reshape(-1), read(name, b)
            if kind == "point":
                keys, where = [int(i) for i in ids], x
            else:
                conn = read("connectivity", b)[:, 1:]
                keys = [tuple(sorted(int(i) for i in ids[c])) for c in conn]
                where = x[conn].mean(axis=1)
            v = v.reshape(len(keys), -1)
            for k, p, val in zip(keys, where, v):
                if k in seen:
                    assert np.array_equal(seen[k][1], val), (k, seen[k][1], val)
                seen[k] = (p, val)
        out["t"].append(float(read("step", 0).reshape(-1)[0]))
        out["points"].append([p.tolist() for p, _ in seen.values()])
        out["values"].append([val.tolist() for _, val in seen.values()])
print(json.dumps(out))
"""


def _run(folder, pair="P2/P1"):
    """A short membrane run that reaches its obstacle, a state every 25 steps."""
    assert cli.main(["membrane", "--pair", pair, "--N", "6", "--dt", "2e-3", "--T", "0.4", "--write-every", "25",
                     "--quiet", "--out", str(folder)]) == 0
    COMM.Barrier()


@pytest.mark.skipif(HAS_VTX, reason="this dolfinx has ADIOS2")
def test_vtx_is_refused_in_one_line_without_adios2(mpi_tmp_path, capsys):
    folder = mpi_tmp_path / "run"
    _run(folder)
    capsys.readouterr()
    assert cli.main(["vtx", str(folder)]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "was built without ADIOS2, which VTX output needs" in err[0]
        assert not (folder / "vtx").exists()


def test_vtx_refuses_what_is_not_a_finished_run(mpi_tmp_path, capsys):
    assert cli.main(["vtx", str(mpi_tmp_path / "nothing")]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("python -m sdm_dolfinx vtx: error:") and "has no run.json" in err[0]


def _read(path, name, kind="point"):
    """The steps of the VTX file ``path`` read by ADIOS2's Python bindings (rank 0)."""
    p = subprocess.run([sys.executable, "-c", READER, str(path), name, kind], capture_output=True, text=True,
                       timeout=120)
    if p.returncode != 0 and "No module named 'adios2'" in p.stderr:
        pytest.fail("ADIOS2's Python bindings (PyPI's adios2) are needed to read the VTX files back")
    assert p.returncode == 0, p.stderr[-2000:]
    return {k: [np.asarray(a) for a in v] for k, v in json.loads(p.stdout).items()}


@pytest.mark.skipif(not HAS_VTX, reason="this dolfinx has no ADIOS2 (VTX)")
@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_the_vtx_files_hold_the_runs_fields(pair, mpi_tmp_path):
    """The displacement is state.h5's dof vector at the same points, to round-off (P2 as it is; P1+ as its
    exact P3 interpolant, compared at the points both have: the vertices); the velocity's kinetic energy
    1/2 sum_i c_i v_i^2 (c_i = int psi_i: the lumped P1 C at the vertices, a cell's area for P0) is
    timeseries.csv's, at every stored step, to 1e-10."""
    folder = mpi_tmp_path / "run"
    _run(folder, pair)
    assert cli.main(["vtx", str(folder)]) == 0
    COMM.Barrier()
    if COMM.rank != 0:
        return
    import csv

    import h5py
    from scipy.spatial import cKDTree
    with h5py.File(folder / "state.h5", "r") as h5:
        U, t = np.asarray(h5["U"]), np.asarray(h5["t"])
        xw = np.asarray(h5["W/dof_coordinates"])[:, :2]
    with open(folder / "timeseries.csv") as fh:
        kinetic = {round(float(r["t"]), 9): float(r["kinetic"]) for r in csv.DictReader(fh)}
    disp = _read(folder / "vtx" / "displacement.bp", "displacement")
    vel = _read(folder / "vtx" / "velocity.bp", "velocity", "cell" if pair == "P1+/P0" else "point")
    assert len(disp["t"]) == len(vel["t"]) == len(t) >= 5
    assert np.allclose(disp["t"], t, rtol=0, atol=1e-12) and np.allclose(vel["t"], t, rtol=0, atol=1e-12)
    c_of = _lumped_masses(pair)
    for k in range(len(t)):
        d, idx = cKDTree(disp["points"][k][:, :2]).query(xw)
        assert d.max() < 1e-12                      # every dof point of W^h is a node of the file
        # P1+: the vertex dofs are values there, the bubble's (at the centroids) a coefficient: the 7 x 7 vertices
        common = np.all(np.isclose(xw * 6, np.round(xw * 6)), axis=1) if pair == "P1+/P0" else d < 1e-12
        assert common.sum() == (49 if pair == "P1+/P0" else len(xw))
        u = disp["values"][k].reshape(-1)
        assert np.max(np.abs(u[idx[common]] - U[k][common])) <= 1e-13 * max(np.abs(U[k]).max(), 1e-300)
        v = vel["values"][k].reshape(-1)
        ke = 0.5 * float(np.sum(c_of(vel["points"][k][:, :2], len(v)) * v ** 2))
        ref = kinetic[round(float(t[k]), 9)]
        assert abs(ke - ref) <= 1e-10 * max(abs(ref), 1e-12), (k, ke, ref)


def _lumped_masses(pair):
    """c(points, n): the diagonal C of the membrane's velocity space (N = 6, rho = 1) at n values: for P0 every
    cell's area (the unit square's 72 equal triangles: no order needed); for lumped P1 int psi_i, assembled
    here on one process and matched to the points by their coordinates."""
    if pair == "P1+/P0":
        return lambda points, n: np.full(n, 1.0 / 72.0)
    from scipy.spatial import cKDTree
    from sdm_dolfinx.problems import get
    msh = get("membrane").problem(MPI.COMM_SELF, N=6).mesh
    P1 = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 1))
    c = compat.assemble_vector(compat.form(ufl.TestFunction(P1) * ufl.dx)).array.copy()
    x = P1.tabulate_dof_coordinates()[:, :2]

    def at(points, n):
        d, idx = cKDTree(x).query(points)
        assert n == len(points) == len(x) and d.max() < 1e-12
        return c[idx]
    return at
