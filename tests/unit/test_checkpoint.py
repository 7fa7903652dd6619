"""Checkpoints (io/checkpoint.py): a state saved and restored is the same state, whatever the
partition; mesh fingerprints; truncation of the time series; one-line errors.

The checkpoint stores values with their dof coordinates, so a state saved on 2 ranks must
restore on 1 rank (the mesh rebuilt on MPI.COMM_SELF) -- tested under mpirun -n 2; serially
the two communicators coincide and the test still checks the round trip. Values are those of
an interpolated smooth field f, different at different points, so a permuted restore fails.
"""
import zipfile

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.io import checkpoint as ck

COMM = MPI.COMM_WORLD
N = 4


def field(x):
    """Smooth, injective enough on the grid: different values at different dof points."""
    return np.vstack([1.0 + x[0] + 3.0 * x[1] ** 2 + 0.7 * x[0] * x[1], -2.0 + np.sin(3 * x[0]) + x[1]])


def space(comm, pair, shape, n=N):
    msh = dmesh.create_unit_square(comm, n, n, dmesh.CellType.triangle)
    return compat.function_space(msh, get_pair(pair).w_element(compat.cell_name(msh), shape))


def vector_of(V, scale=1.0):
    """The PETSc vector of the interpolant of scale * field (scalar: its first row)."""
    f = fem.Function(V)
    f.interpolate(lambda x: scale * (field(x) if V.dofmap.index_map_bs == 2 else field(x)[0]))
    return compat.petsc_vec(f).copy()


CASES = [("P2/P1", ()), ("P1+/P0", ()), ("P2/P1", (2,)), ("P1+/P0", (2,))]


@pytest.mark.parametrize("pair, shape", CASES)
def test_round_trip_same_partition(mpi_tmp_path, pair, shape):
    V = space(COMM, pair, shape)
    U, Vel = vector_of(V), vector_of(V, -0.5)
    active = np.array([[0.25, 0.5, 0.0]]) if COMM.rank == 0 else np.zeros((0, 3))
    meta = {"step": 17, "t": 0.017, "problem": {"name": "membrane", "args": {"N": N}}}
    ck.save(mpi_tmp_path, COMM, {"U": (V, U), "V": (V, Vel)}, active, meta)
    data, meta2 = ck.load(mpi_tmp_path, COMM)
    assert meta2 == meta
    U2, V2 = U.duplicate(), Vel.duplicate()
    U2.set(np.nan)
    V2.set(np.nan)
    ck.restore(data, {"U": (V, U2), "V": (V, V2)}, COMM)
    # the stored float64 values come back bit for bit, at the same dofs
    assert np.array_equal(U2.array, U.array) and np.array_equal(V2.array, Vel.array)
    # the active vertices are recognised by their coordinates
    cx = np.array([[0.25, 0.75, 0.5], [0.5, 0.5, 0.25], [0.0, 0.0, 0.0]])
    assert ck.active_mask(data, cx).tolist() == [True, False, False]


@pytest.mark.parametrize("pair, shape", CASES)
def test_round_trip_onto_one_rank(mpi_tmp_path, pair, shape):
    V = space(COMM, pair, shape)
    ck.save(mpi_tmp_path, COMM, {"U": (V, vector_of(V))}, np.zeros((0, 3)), {"step": 1})
    # every rank reads the file with its own one-rank copy of the mesh
    COMM.Barrier()
    data, _ = ck.load(mpi_tmp_path, MPI.COMM_SELF)
    Vs = space(MPI.COMM_SELF, pair, shape)
    Us = vector_of(Vs)
    R = Us.duplicate()
    R.set(np.nan)
    ck.restore(data, {"U": (Vs, R)}, MPI.COMM_SELF)
    # interpolation on another partition evaluates f at the same points up to round-off in
    # the dof coordinates (~1e-16): the restored values equal the local interpolant to 1e-14
    assert R.getSize() == Vs.dofmap.index_map.size_global * Vs.dofmap.index_map_bs
    assert np.allclose(R.array, Us.array, rtol=0, atol=1e-14 * np.abs(Us.array).max())


def test_restore_on_another_mesh_is_refused(mpi_tmp_path):
    V = space(COMM, "P2/P1", ())
    ck.save(mpi_tmp_path, COMM, {"U": (V, vector_of(V))}, np.zeros((0, 3)), {})
    data, _ = ck.load(mpi_tmp_path, COMM)
    other = space(COMM, "P2/P1", (), n=N + 1)
    with pytest.raises(ck.CheckpointError) as e:
        ck.restore(data, {"U": (other, vector_of(other))}, COMM)
    assert "U dofs do not match" in str(e.value)


# ------------------------------------------------------------------------------ fingerprint
def test_mesh_fingerprint_closed_form_and_partition_independent():
    msh = dmesh.create_unit_square(COMM, N, N)
    fp = ck.mesh_fingerprint(msh)
    # vertices i/N: sum over the (N+1)^2 points of x + y = (N+1)^2, of x^2 + y^2 =
    # 2 (N+1) sum_i (i/N)^2 = (N+1)^2 (2N+1) / (3N)
    assert fp["vertices"] == (N + 1) ** 2 and fp["cells"] == 2 * N ** 2
    assert abs(fp["x_sum"] - (N + 1) ** 2) <= 1e-13 * (N + 1) ** 2
    x2 = (N + 1) ** 2 * (2 * N + 1) / (3 * N)
    assert abs(fp["x2_sum"] - x2) <= 1e-13 * x2
    # the same mesh on one rank: the same fingerprint (sums in another order: rtol 1e-12)
    assert ck.same_fingerprint(ck.mesh_fingerprint(dmesh.create_unit_square(MPI.COMM_SELF, N, N)), fp)


def test_mesh_fingerprint_tells_meshes_apart():
    fp = ck.mesh_fingerprint(dmesh.create_unit_square(COMM, N, N))
    finer = ck.mesh_fingerprint(dmesh.create_unit_square(COMM, N + 1, N + 1))
    crossed = ck.mesh_fingerprint(dmesh.create_unit_square(COMM, N, N, diagonal=dmesh.DiagonalType.crossed))
    # same counts, vertices moved by 1e-6 of the size: the coordinate sums differ
    moved = ck.mesh_fingerprint(dmesh.create_rectangle(COMM, [np.zeros(2), np.array([1.0 + 1e-6, 1.0])], [N, N]))
    for other in (finer, crossed, moved):
        assert not ck.same_fingerprint(other, fp)
    assert moved["vertices"] == fp["vertices"] and moved["cells"] == fp["cells"]


# ------------------------------------------------------------------------------ csv
HEADER = "step,t,energy"


def write(path, text):
    if COMM.rank == 0:
        path.write_text(text)
    COMM.Barrier()


def read(path):
    return COMM.bcast(path.read_text() if COMM.rank == 0 else None, root=0)


def test_truncate_csv_keeps_whole_rows(mpi_tmp_path):
    path = mpi_tmp_path / "timeseries.csv"
    rows = [f"{n},{n * 1e-3:.3e},{0.012 + n * 1e-5:.6e}" for n in range(8)]
    write(path, "\n".join([HEADER] + rows) + "\n8,8.000e-0")      # a kill tore the last line
    kept = ck.truncate_csv(path, 5, COMM)
    assert kept == [HEADER] + rows[:6]                               # steps 0..5
    assert read(path) == "\n".join([HEADER] + rows[:6]) + "\n"
    # beyond the last whole row: every whole row stays, the torn one goes
    write(path, "\n".join([HEADER] + rows) + "\n8,8.000e-0")
    assert ck.truncate_csv(path, 100, COMM) == [HEADER] + rows


def test_truncate_csv_drops_a_line_torn_after_a_comma(mpi_tmp_path):
    path = mpi_tmp_path / "timeseries.csv"
    rows = [f"{n},{n * 1e-3:.3e},{0.012:.6e}" for n in range(3)]
    write(path, "\n".join([HEADER] + rows) + "\n3,3.000e-03,")
    assert ck.truncate_csv(path, 100, COMM) == [HEADER] + rows


# ------------------------------------------------------------------------------ errors
def one_line(exc):
    msg = str(exc.value)
    assert msg and "\n" not in msg
    return msg


def test_missing_checkpoint(mpi_tmp_path):
    with pytest.raises(ck.CheckpointError) as e:
        ck.load(mpi_tmp_path, COMM)
    assert "no checkpoint in" in one_line(e)


def test_damaged_checkpoint(mpi_tmp_path):
    write_bytes(mpi_tmp_path / ck.CHECKPOINT, b"\x00garbage" * 64)
    with pytest.raises(ck.CheckpointError) as e:
        ck.load(mpi_tmp_path, COMM)
    assert "cannot read" in one_line(e)


def test_checkpoint_without_meta(mpi_tmp_path):
    if COMM.rank == 0:
        np.savez(mpi_tmp_path / ck.CHECKPOINT, U=np.zeros(3))
    COMM.Barrier()
    with pytest.raises(ck.CheckpointError) as e:
        ck.load(mpi_tmp_path, COMM)
    assert "cannot read" in one_line(e)


def write_bytes(path, data):
    if COMM.rank == 0:
        path.write_bytes(data)
    COMM.Barrier()


def test_truncated_checkpoint(mpi_tmp_path):
    # each rank reads through MPI.COMM_SELF so that the bug cannot hang the other rank
    V = space(COMM, "P2/P1", ())
    ck.save(mpi_tmp_path, COMM, {"U": (V, vector_of(V))}, np.zeros((0, 3)), {"step": 3})
    path = mpi_tmp_path / ck.CHECKPOINT
    if COMM.rank == 0:
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    COMM.Barrier()
    with pytest.raises(ck.CheckpointError):
        ck.load(mpi_tmp_path, MPI.COMM_SELF)
