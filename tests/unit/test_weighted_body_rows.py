"""The weighted gap between bodies (``constrain="weighted"`` with contact pairs,
sdm_dolfinx/method/weighted_body_rows.py): what its rows are, checked against closed forms.

Two plane bars on non-matching meshes (demos/two_bars_problem.py, the slave face x = -d of bar 1 with 3
cells across, the master face x = d of bar 2 with 2), in a state that moves the slave face by
u_x = a + b y and the master face by u_x = c: the master stays flat, its normal is -e_x, and the signed
distance of a slave point at height y is the linear phi(y) = 2 d + c - a - b y. Each node's row (node to
surface) reads phi exactly at its node, the gap's W^h interpolant is phi itself (linear), so row i of the
weighted gap is int_S psi_i phi ds / int_S psi_i ds, computed here independently with UFL on the slave
facets (to round-off). The vertex rows read phi at the vertex.
"""
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.problems import load_file

COMM = MPI.COMM_WORLD
DEMOS = Path(__file__).resolve().parents[2] / "demos"
A, B, C = 2e-3, -5e-4, 1e-3          # the slave face's u_x = A + B y, the master's u_x = C (mm)


def _state(d):
    """The state (owned dofs of W^h) and the whole vector gathered on every rank (global numbering)."""
    bs = d.W.dofmap.index_map_bs
    n = d.W.dofmap.index_map.size_local
    x = d._dof_x()[:n]
    u = np.zeros((n, bs))
    u[:, 0] = np.where(x[:, 0] < 0.0, A + B * x[:, 1], C)
    u = u.reshape(-1)
    return u, np.concatenate(COMM.allgather(u))


def _row_values(rows, u, whole):
    (ids, vals), g = rows.rows(u, 0.0, 1e-6, 0.5)
    return np.einsum("ik,ik->i", vals, whole[ids]) - g, ids, vals


@pytest.mark.mpi
@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_the_weighted_rows_are_the_hat_function_averages_of_a_linear_gap(pair):
    p = load_file(DEMOS / "two_bars_problem.py").problem(COMM, Nx=4, Ny=2, Ny1=3)
    gap = p.parameters["gap"]
    d = Discretisation(p, pair, constrain="weighted")
    u, whole = _state(d)
    got, ids, vals = _row_values(d.body_rows, u, whole)
    # the reference: int psi_i phi ds / int psi_i ds over the slave facets, at the slave vertices' P1 dofs
    msh = p.mesh
    slave = np.asarray(p.contact_pairs[0].slave(msh), dtype=np.int32)
    tags = dmesh.meshtags(msh, msh.topology.dim - 1, slave, np.full(len(slave), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": 4})(1)
    q, y = ufl.TestFunction(d.Q1), ufl.SpatialCoordinate(msh)[1]
    moments = [compat.assemble_vector(compat.form(f * q * ds)) for f in (gap + C - A - B * y, 1.0 + 0.0 * y)]
    for vec in moments:
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    rows = np.asarray(d.q1_of_c)
    expect = moments[0].array_r[rows] / moments[1].array_r[rows]
    assert COMM.allreduce(len(got), op=MPI.SUM) == 4                      # a row per slave vertex
    np.testing.assert_allclose(got, expect, rtol=0.0, atol=1e-13 * p.parameters["L"])   # round-off of coordinates of size L
    # the rows push the bodies equally and oppositely (no resultant): the contact keeps the momentum
    for comp in (0, 1):
        np.testing.assert_allclose(np.sum(np.where(ids % 2 == comp, vals, 0.0), axis=1), 0.0, atol=1e-14)
    # the vertex rows read the gap at the vertex
    vertices = Discretisation(p, pair)
    at, _, _ = _row_values(vertices.body_rows, u, whole)
    np.testing.assert_allclose(at, gap + C - A - B * np.asarray(vertices.cx)[1], rtol=0.0, atol=1e-13 * p.parameters["L"])   # round-off of coordinates of size L


@pytest.mark.mpi
def test_the_weighted_tangential_rows_have_no_resultant_and_one_frame_a_row():
    """With friction, row i's tangential row is its entries' weights along the tangent of row i's normal
    (-e_x here: t = (0, 1)), so it too is equal and opposite on the two bodies."""
    p = load_file(DEMOS / "two_bars_problem.py").problem(COMM, Nx=4, Ny=2, Ny1=3)
    d = Discretisation(p, "P2/P1", constrain="weighted")
    u, whole = _state(d)
    (ids, normal), g = d.body_rows.rows(u, 0.0, 1e-6, 0.5)
    (ids_t, vals), g_t = d.body_rows.rows(u, 0.0, 1e-6, 0.5, tangential=True)
    np.testing.assert_array_equal(ids_t, ids)
    np.testing.assert_array_equal(vals[0], normal)
    for comp in (0, 1):
        np.testing.assert_allclose(np.sum(np.where(ids % 2 == comp, vals[1], 0.0), axis=1), 0.0, atol=1e-14)
    # the normal row reads the x components only, the tangential row the y components only, with weights
    # of the same size (t = (0, 1) against n = (-1, 0) at every node of the flat faces)
    np.testing.assert_allclose(np.where(ids % 2 == 1, normal, 0.0), 0.0, atol=1e-14)
    np.testing.assert_allclose(np.where(ids % 2 == 0, vals[1], 0.0), 0.0, atol=1e-14)
    np.testing.assert_allclose(np.sort(np.abs(vals[1]), axis=1)[:, -1], np.sort(np.abs(normal), axis=1)[:, -1],
                               atol=1e-14)


@pytest.mark.mpi
@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_nodes_beyond_the_masters_rim_leave_the_weighted_rows(pair):
    """The slave face pushed 0.01 mm into the master's plane and slid up by 8 mm: only its bottom vertex
    (y = 0, now at y = 8 on the 10 mm master face) is on the master, and it penetrates. The nodes beyond the
    rim (their closest point on the master's top corner) have no master point: they leave the rows, so the
    rows around the bottom vertex read its gap, -0.01, and the rows of nodes all beyond the rim hold nothing
    (g = -inf). Before, those nodes entered with their distances to the corner and every row was positive."""
    p = load_file(DEMOS / "two_bars_problem.py").problem(COMM, Nx=4, Ny=2, Ny1=3)
    gap = p.parameters["gap"]
    d = Discretisation(p, pair, constrain="weighted")
    bs, n = d.W.dofmap.index_map_bs, d.W.dofmap.index_map.size_local
    x = d._dof_x()[:n]
    u = np.zeros((n, bs))
    u[x[:, 0] < 0.0] = (gap + 0.01, 8.0)
    u = u.reshape(-1)
    got, _, _ = _row_values(d.body_rows, u, np.concatenate(COMM.allgather(u)))
    (_, _), g = d.body_rows.rows(u, 0.0, 1e-6, 0.5)
    y = np.asarray(d.cx)[1]
    held = np.isfinite(g)
    assert COMM.allreduce(int(np.count_nonzero(held)), op=MPI.SUM) == 2        # the vertices at y = 0 and 3.33
    np.testing.assert_allclose(got[held], -0.01, atol=1e-12 * p.parameters["L"])
    assert np.all(y[~held] > 5.0)


def test_dirichlet_data_on_the_slave_face_is_refused_in_one_line():
    """The striker's bottom edge y = 0 clamped: a slave vertex and its face's nodes carry Dirichlet data,
    which the vertex rows drop and the weighted rows would read as unknowns: refused when the rows are built."""
    import dataclasses
    from sdm_dolfinx.method.errors import DiscretisationError
    from sdm_dolfinx.problems import facets_where
    p = load_file(DEMOS / "two_bars_problem.py").problem(COMM, Nx=4, Ny=2, Ny1=3)
    p = dataclasses.replace(p, dirichlet_facets=facets_where(lambda x: np.isclose(x[1], 0.0) & (x[0] < 0)),
                            dirichlet_value=lambda x: np.zeros((2, x.shape[1])))
    Discretisation(p, "P2/P1")                              # the vertex rows take it
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1", constrain="weighted")
    text = str(e.value)
    assert "\n" not in text and "carry Dirichlet data" in text and "use constrain='vertices'" in text
