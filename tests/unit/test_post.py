"""Unit tests of the post-processing layer (sdm_dolfinx.post): mathematical facts with stated
tolerances, on any number of ranks (serially and under ``mpirun -n 2``).

Tolerances: quantities that are exact in exact arithmetic (a polynomial of the element's
degree, an integral the quadrature integrates exactly) are asked to agree to 1e-12, a few
thousand eps for sums over O(100) terms.
"""
import math

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx import compat, post
from sdm_dolfinx.problems import load_file, membrane
from sdm_dolfinx.io.checkpoint import mesh_fingerprint

COMM = MPI.COMM_WORLD
EXACT = 1e-12


def _space(msh, degree):
    return compat.function_space(msh, compat.element("Lagrange", "triangle", degree))


def _max_abs(a):
    return COMM.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


# ------------------------------------------------------------------------------ h1_norm
def _linear(x):
    return 1.0 + 2.0 * x[0] - 3.0 * x[1]


def _quadratic(x):
    return x[0] ** 2 + x[0] * x[1]


# u, degree, int u^2, int |grad u|^2 on the unit square (closed forms):
#   (1 + 2x - 3y)^2 = 1 + 4x^2 + 9y^2 + 4x - 6y - 12xy  ->  1 + 4/3 + 3 + 2 - 3 - 3 = 4/3;  |grad u|^2 = 13
#   (x^2 + xy)^2 -> 1/5 + 1/4 + 1/9 = 101/180;  |grad u|^2 = (2x + y)^2 + x^2 -> 4/3 + 1 + 1/3 + 1/3 = 3
@pytest.mark.parametrize("u, degree, l2, grad", [(_linear, 1, 4 / 3, 13.0), (_quadratic, 2, 101 / 180, 3.0)],
                         ids=["P1", "P2"])
def test_h1_norm_closed_form_on_the_unit_square(u, degree, l2, grad):
    f = fem.Function(_space(dmesh.create_unit_square(COMM, 6, 5), degree))
    f.interpolate(u)                              # exact: u is in the space
    assert post.h1_norm(f) == pytest.approx(math.sqrt(l2 + grad), rel=EXACT)
    assert post.h1_norm(f, seminorm=True) == pytest.approx(math.sqrt(grad), rel=EXACT)
    assert post.h1_norm(f, l2_weight=1e-6) == pytest.approx(math.sqrt(1e-6 * l2 + grad), rel=EXACT)


def test_h1_error_of_a_constant_shift():
    """u = ref + 0.1: the error is 0.1 in L^2 and 0 in the gradient; |1 + x|^2_H1 = 7/3 + 1."""
    V = _space(dmesh.create_unit_square(COMM, 4, 4), 1)
    u, ref = fem.Function(V), fem.Function(V)
    ref.interpolate(lambda x: 1.0 + x[0])
    u.interpolate(lambda x: 1.1 + x[0])
    assert post.h1_error(u, ref) == pytest.approx(0.1 / math.sqrt(10.0 / 3.0), rel=EXACT)
    assert post.h1_error(u, ref, seminorm=True) == pytest.approx(0.0, abs=EXACT)


# --------------------------------------------------------------------- non-matching meshes
def _two_meshes():
    """Two unrelated meshes of the unit square (different sizes and diagonals, so different partitions)."""
    return (dmesh.create_unit_square(COMM, 7, 5, diagonal=dmesh.DiagonalType.right),
            dmesh.create_unit_square(COMM, 4, 6, diagonal=dmesh.DiagonalType.crossed))


@pytest.mark.parametrize("degree, poly", [(1, _linear), (2, _quadratic)], ids=["P1", "P2"])
def test_evaluate_nonmatching_reproduces_a_polynomial(degree, poly):
    """Points spread differently on every rank, inside the square and up to 0.05 outside it
    (extrapolated from the nearest cell: still the polynomial, which is the same on every cell)."""
    src, _ = _two_meshes()
    u = fem.Function(_space(src, degree))
    u.interpolate(poly)
    rng = np.random.default_rng(7 + COMM.rank)
    pts = np.zeros((40 + 3 * COMM.rank, 3))
    pts[:, :2] = rng.uniform(0.0, 1.0, (len(pts), 2))
    pts[-1, :2] = (1.05, 0.5)                      # outside, within the padding
    vals, dist = post.evaluate_nonmatching(u, pts, padding=0.1)
    assert vals.shape == (len(pts), 1)
    assert np.max(np.abs(vals[:, 0] - poly(pts.T))) < EXACT
    assert np.all(dist[:-1] == 0.0) and dist[-1] == pytest.approx(0.05, abs=EXACT)


def test_evaluate_nonmatching_refuses_a_point_beyond_the_padding():
    src, _ = _two_meshes()
    u = fem.Function(_space(src, 1))
    pts = np.array([[2.0, 2.0, 0.0]]) if COMM.rank == 0 else np.zeros((0, 3))
    with pytest.raises(sdm_io.PostprocessError, match="farther"):
        post.evaluate_nonmatching(u, pts, padding=1e-3)


@pytest.mark.parametrize("degrees, poly", [((1, 1), _linear), ((1, 2), _linear), ((2, 2), _quadratic)],
                         ids=["P1-P1", "P1-P2", "P2-P2"])
@pytest.mark.parametrize("transfer", ["interpolate_by_points", "interpolate_nonmatching"])
def test_interpolation_between_meshes_is_exact_for_polynomials(degrees, poly, transfer):
    src, dst = _two_meshes()
    u_src, u_dst, exact = (fem.Function(_space(src, degrees[0])), fem.Function(_space(dst, degrees[1])),
                           fem.Function(_space(dst, degrees[1])))
    u_src.interpolate(poly)
    exact.interpolate(poly)
    stats = getattr(post, transfer)(u_dst, u_src)
    assert _max_abs(u_dst.x.array - exact.x.array) < EXACT
    if "max_distance" in stats:                    # the point-evaluation path: every point inside
        assert COMM.allreduce(stats["max_distance"], op=MPI.MAX) == 0.0


# ---------------------------------------------------------------------------- rates
@pytest.mark.parametrize("order", [1.0, 2.0, 2.5])
def test_convergence_rate_of_exact_power_laws(order):
    h = np.array([0.4, 0.2, 0.1, 0.05])
    assert post.convergence_rate(h, 3.7 * h ** order) == pytest.approx(order, abs=EXACT)


def test_convergence_rate_needs_two_positive_points():
    with pytest.raises(ValueError):
        post.convergence_rate([0.1], [0.01])
    with pytest.raises(ValueError):
        post.convergence_rate([0.1, 0.05], [0.01, 0.0])


# ------------------------------------------------------------------------- reading files
def test_read_timeseries_of_a_hand_written_csv(mpi_tmp_path):
    """Every column as floats on every rank; a row cut short (a killed run) is skipped."""
    if COMM.rank == 0:
        (mpi_tmp_path / "timeseries.csv").write_text("step,t,energy\n0,0.0,1.5\n1,0.001,1.25e-1\n\n2,0.002,-3\n3,0.0\n")
    COMM.Barrier()
    ts = sdm_io.read_timeseries(mpi_tmp_path, COMM)
    assert list(ts) == ["step", "t", "energy"]
    np.testing.assert_array_equal(ts["step"], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(ts["t"], [0.0, 0.001, 0.002])
    np.testing.assert_array_equal(ts["energy"], [1.5, 0.125, -3.0])


def test_read_timeseries_of_a_missing_file_is_one_error_on_every_rank(mpi_tmp_path):
    with pytest.raises(sdm_io.PostprocessError, match="no timeseries.csv"):
        sdm_io.read_timeseries(mpi_tmp_path / "nothing", COMM)


# ------------------------------------------------------------------------------ rebuild
def test_rebuild_of_a_declared_problem_gives_the_same_mesh():
    prob = membrane.problem(COMM, N=3, diagonal="left_right")
    again = post.rebuild_problem({"problem": prob.describe()}, COMM)
    assert again.parameters == prob.parameters and again.args == prob.args
    assert mesh_fingerprint(again.mesh) == mesh_fingerprint(prob.mesh)


def test_rebuild_of_a_problem_file(mpi_tmp_path):
    """A problem declared in a file: run.json's ``source`` finds the file again."""
    path = mpi_tmp_path / "square.py"
    if COMM.rank == 0:
        path.write_text("from sdm_dolfinx.problems import ProblemSpec, membrane\n"
                        f"PROBLEM = ProblemSpec(name='square_{mpi_tmp_path.name}', build=membrane.SPEC.build, "
                        "params=membrane.PARAMS)\n")
    COMM.Barrier()
    prob = load_file(path).problem(COMM, N=2)
    again = post.rebuild_problem({"problem": prob.describe()}, COMM)
    assert again.args == prob.args and again.parameters["N"] == 2


def test_rebuild_of_a_problem_built_by_hand_is_one_line():
    """No declaration (no ``args`` in run.json): one line saying so, on every rank."""
    prob = membrane.SPEC.build(COMM, **membrane.SPEC.values({"N": 2}))
    with pytest.raises(sdm_io.PostprocessError, match="without a declaration") as e:
        post.rebuild_problem({"problem": prob.describe()}, COMM)
    assert "\n" not in str(e.value)
    with pytest.raises(sdm_io.PostprocessError, match="no 'problem' entry"):
        post.rebuild_problem({}, COMM)
