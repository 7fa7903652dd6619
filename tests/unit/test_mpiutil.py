"""mpiutil: gathering to rank 0 gives the global array, on_rank0 broadcasts results and
errors to every rank, atomic writes never leave a half-written file, JSON takes numpy values.

Every expectation is a closed form of the distribution (global index i at row i; rank r's
rows are r's in rank order), so the same assertions hold on 1 and 2 ranks.
"""
import json
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
from dolfinx import mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import (atomic_write, atomic_write_text, gather_blocks, gather_ranges, gather_rows,
                                 gather_vec, json_text, on_rank0, write_json)

COMM = MPI.COMM_WORLD


def shared(value):
    """Rank 0's value on every rank (assertions are then made on every rank)."""
    return COMM.bcast(value, root=0)


def test_gather_vec():
    n = 11                                            # not a multiple of the ranks
    v = PETSc.Vec().createMPI(n, comm=COMM)
    lo, hi = v.getOwnershipRange()
    v.array[:] = 0.5 * np.arange(lo, hi)
    out = gather_vec(v, COMM)
    assert (out is None) == (COMM.rank != 0)
    assert shared(None if out is None else out.tolist()) == (0.5 * np.arange(n)).tolist()
    v.destroy()


def test_gather_ranges_keeps_row_shape():
    # rows of 3 values owned from start on, as the blocks of a vector field
    n = 7
    sizes = [n // COMM.size + (r < n % COMM.size) for r in range(COMM.size)]
    start = sum(sizes[:COMM.rank])
    rows = np.arange(start, start + sizes[COMM.rank])[:, None] * np.array([1, 10, 100])
    out = gather_ranges(start, rows, n, COMM)
    ref = np.arange(n)[:, None] * np.array([1, 10, 100])
    assert shared(None if out is None else (out.shape == (n, 3) and np.array_equal(out, ref)))


def test_gather_rows_in_rank_order():
    # rank r contributes r + 1 rows of value r: rank order, nothing lost
    part = np.full((COMM.rank + 1, 2), float(COMM.rank))
    out = gather_rows(part, COMM)
    ref = np.concatenate([np.full((r + 1, 2), float(r)) for r in range(COMM.size)])
    assert shared(None if out is None else np.array_equal(out, ref))
    # a rank with no rows is fine
    out = gather_rows(np.zeros((0, 3)) if COMM.rank else np.ones((2, 3)), COMM)
    assert shared(None if out is None else out.shape) == (2, 3)


def test_gather_blocks_in_global_block_order():
    N = 3
    msh = dmesh.create_unit_square(COMM, N, N)
    V = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 1))
    im = V.dofmap.index_map
    # each owned block's global number, plus ghost rows that must be ignored
    values = np.concatenate([im.local_range[0] + np.arange(im.size_local), np.full(im.num_ghosts, -1)])
    out = gather_blocks(V, values, COMM)
    assert shared(None if out is None else out.tolist()) == list(range((N + 1) ** 2))
    # per-block rows: the dof coordinates gathered are the (N+1)^2 grid points, each once
    x = gather_blocks(V, V.tabulate_dof_coordinates()[:, :2], COMM)
    grid = sorted((i / N, j / N) for i in range(N + 1) for j in range(N + 1))
    got = shared(None if x is None else sorted(map(tuple, np.round(x, 12))))
    assert np.allclose(got, grid, atol=1e-12)


class MyError(RuntimeError):
    pass


def test_on_rank0_broadcasts_the_result():
    calls = []

    def work(a, b):
        calls.append(COMM.rank)
        return {"sum": a + b, "rank": COMM.rank}
    assert on_rank0(COMM, work, 2, 3) == {"sum": 5, "rank": 0}     # computed on rank 0 only
    assert calls == ([0] if COMM.rank == 0 else [])


@pytest.mark.parametrize("exc, text", [(OSError("disk full"), "OSError: disk full"),
                                       (KeyError("step"), "KeyError: 'step'"),
                                       (MyError("already one line"), "already one line")])
def test_on_rank0_raises_on_every_rank(exc, text):
    def fail():
        raise exc
    with pytest.raises(MyError) as e:
        on_rank0(COMM, fail, wrap=MyError)
    assert str(e.value) == text


def test_on_rank0_custom_error_types():
    def fail():
        raise ZeroDivisionError("x / 0")
    with pytest.raises(MyError) as e:
        on_rank0(COMM, fail, errors=(ZeroDivisionError,), wrap=MyError)
    assert str(e.value) == "ZeroDivisionError: x / 0"


def test_atomic_write_keeps_the_old_file_when_the_writer_raises(mpi_tmp_path):
    path = mpi_tmp_path / "run.json"
    ok = True
    if COMM.rank == 0:                                # not collective: rank 0 writes
        atomic_write_text(path, "old\n")

        def torn(tmp):
            Path(tmp).write_text("half")
            raise KeyboardInterrupt                    # even a BaseException (SIGINT)
        try:
            atomic_write(path, torn)
            ok = False
        except KeyboardInterrupt:
            pass
        try:
            atomic_write_text(path, 42)                # the text writer itself raises
            ok = False
        except TypeError:
            pass
        ok = ok and path.read_text() == "old\n" and sorted(p.name for p in mpi_tmp_path.iterdir()) == ["run.json"]
        atomic_write_text(path, "new\n")
        ok = ok and path.read_text() == "new\n"
    assert shared(ok)


def test_json_text_numpy_and_paths(mpi_tmp_path):
    data = {"f64": np.float64(0.1), "i32": np.int32(-7), "b": np.bool_(True), "arr": np.arange(6).reshape(2, 3),
            "farr": np.array([0.5, 1e-300]), "path": Path("/tmp/x.h5"), "plain": [1, "a", None]}
    text = json_text(data)
    assert text.endswith("\n")
    back = json.loads(text)
    assert back == {"f64": 0.1, "i32": -7, "b": True, "arr": [[0, 1, 2], [3, 4, 5]], "farr": [0.5, 1e-300],
                    "path": "/tmp/x.h5", "plain": [1, "a", None]}
    assert type(back["i32"]) is int and type(back["b"]) is bool
    with pytest.raises(TypeError):
        json_text({"x": object()})
    write_json(mpi_tmp_path / "d.json", data, COMM)
    assert shared(json.loads((mpi_tmp_path / "d.json").read_text()) if COMM.rank == 0 else None) == back
