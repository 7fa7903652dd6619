"""Post-processing: fields reloaded from state.h5, the energy recomputed from them, interpolation between non-matching meshes (serial and on 2 ranks)."""
import csv

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx import cli, compat, post, simulate
from sdm_dolfinx.problems import disc, membrane
from sdm_dolfinx.run.probes import PointProbe

COMM = MPI.COMM_WORLD


def _linear(x):
    return 0.3 + 1.7 * x[0] - 2.9 * x[1]


def _max_abs(a, comm=COMM):
    return comm.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


def _read_csv(path):
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("degrees", [(1, 2), (2, 1), (2, 2)])
def test_linear_field_exact_across_nonmatching_squares(degrees):
    """A linear field survives the transfer between two unrelated meshes of the unit square exactly."""
    src = dmesh.create_unit_square(COMM, 7, 5, diagonal=dmesh.DiagonalType.right)
    dst = dmesh.create_unit_square(COMM, 4, 6, diagonal=dmesh.DiagonalType.crossed)
    Vs = compat.function_space(src, compat.element("Lagrange", "triangle", degrees[0]))
    Vd = compat.function_space(dst, compat.element("Lagrange", "triangle", degrees[1]))
    us, ud, exact = fem.Function(Vs), fem.Function(Vd), fem.Function(Vd)
    us.interpolate(_linear)
    exact.interpolate(_linear)
    post.interpolate_nonmatching(ud, us)
    assert _max_abs(ud.x.array - exact.x.array) < 50 * np.finfo(float).eps


def test_linear_vector_field_exact_between_disc_levels():
    """Curved P2 meshes of the disc at two levels: points of one just outside the other
    (their circles are approximated differently) are extrapolated, still exactly."""
    coarse = disc.problem(level=1).mesh
    fine = disc.problem(level=2).mesh
    el = compat.element("Lagrange", "triangle", 2, (2,))
    Vc, Vf = compat.function_space(coarse, el), compat.function_space(fine, el)

    def field(x):
        return np.vstack([1.0 + 0.02 * x[0] - 0.05 * x[1], -3.0 + 0.04 * x[0] + 0.01 * x[1]])
    for src_space, dst_space in ((Vc, Vf), (Vf, Vc)):
        src, dst, exact = fem.Function(src_space), fem.Function(dst_space), fem.Function(dst_space)
        src.interpolate(field)
        exact.interpolate(field)
        stats = post.interpolate_nonmatching(dst, src, padding=0.5)
        assert _max_abs(dst.x.array - exact.x.array) < 1e-11
        if "max_distance" in stats:       # the 0.5 path reports how far it extrapolated
            assert COMM.allreduce(stats["max_distance"], op=MPI.MAX) > 0


def test_point_far_outside_is_refused():
    src = dmesh.create_unit_square(COMM, 3, 3)
    u = fem.Function(compat.function_space(src, compat.element("Lagrange", "triangle", 1)))
    pts = np.array([[2.0, 2.0, 0.0]]) if COMM.rank == 0 else np.zeros((0, 3))
    with pytest.raises(sdm_io.PostprocessError, match="farther"):
        post.evaluate_nonmatching(u, pts, padding=1e-3)


def test_h1_error_of_shifted_field():
    msh = dmesh.create_unit_square(COMM, 8, 8)
    V = compat.function_space(msh, compat.element("Lagrange", "triangle", 2))
    u, ref = fem.Function(V), fem.Function(V)
    ref.interpolate(lambda x: 1.0 + x[0])          # |ref|_H1^2 = int (1+x)^2 + 1 = 7/3 + 1
    u.interpolate(lambda x: 1.1 + x[0])            # error 0.1, gradient error 0
    assert post.h1_error(u, ref) == pytest.approx(0.1 / np.sqrt(10.0 / 3.0), rel=1e-12)


@pytest.mark.parametrize("slope", [0.69, 1.0, 2.5])
def test_convergence_rate_of_synthetic_data(slope):
    h = np.array([2.0, 1.0, 0.5, 0.25])
    assert abs(post.convergence_rate(h, 0.037 * h ** slope) - slope) < 1e-6


@pytest.mark.parametrize("args", [
    ["membrane", "--N", "4", "--pair", "P1+/P0", "--dt", "0.01", "--T", "0.3"],
    ["membrane", "--N", "4", "--pair", "P2/P1", "--mass", "consistent", "--dt", "0.01", "--T", "0.3"],
    ["membrane", "--N", "4", "--pair", "P1/P1", "--scheme", "backward-euler", "--dt", "0.02", "--T", "0.4"],
    ["disc", "--level", "1", "--pair", "P2/P1", "--dt", "0.001", "--T", "0.014"],
], ids=["P1+P0", "P2P1-consistent", "P1P1-BE", "disc"])
def test_energy_recomputed_from_fields_matches_timeseries(mpi_tmp_path, args, capsys):
    """Written at every step, the fields give back the in-run energy to round-off."""
    out = mpi_tmp_path / "run"
    assert cli.main(args + ["--out", str(out), "--write-every", "1", "--quiet"]) == 0
    assert cli.main(["energy", str(out)]) == 0
    if COMM.rank == 0:
        assert "max relative difference" in capsys.readouterr().out
        rec, ts = _read_csv(out / "energy_recomputed.csv"), _read_csv(out / "timeseries.csv")
        assert np.array_equal(rec["step"], ts["step"])             # every step was written
    res = post.recompute_energy(out, COMM, write=False)
    eps = np.finfo(np.dtype(res["stored_dtype"])).eps
    # round-off: within a few hundred eps of what summation order can change (float64 storage)
    assert res["stored_dtype"] == "float64"
    assert res["max_roundoff_ratio"] <= 300 * eps
    assert res["max_rel_diff"] <= 1e-9


def test_state_written_on_one_rank_is_read_on_all(mpi_tmp_path):
    """A run written by rank 0 alone is reloaded on every rank of COMM_WORLD: dofs are
    matched by their coordinates, not by the writer's numbering."""
    out = mpi_tmp_path / "serial"
    if COMM.rank == 0:
        simulate(membrane.problem(MPI.COMM_SELF, N=5), pair="P2/P1", dt=0.02, T=0.4, out=out, write_every=4)
    COMM.Barrier()
    info, problem, W, Vs = post.rebuild(out, COMM)
    reader = sdm_io.StateReader(out, W, Vs, COMM)
    u, _ = reader.read(len(reader) - 1)
    ts = sdm_io.read_timeseries(out, COMM)
    # the probe value at the centre from the reloaded field equals the run's own record
    probe = PointProbe(W, (0.5, 0.5))
    assert probe(compat.petsc_vec(u)) == pytest.approx(ts["u_probe"][-1], abs=1e-6 * 0.02)
    res = post.recompute_energy(out, COMM, write=False)
    assert res["max_roundoff_ratio"] <= 300 * np.finfo(np.dtype(res["stored_dtype"])).eps

