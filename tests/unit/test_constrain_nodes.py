"""``Discretisation(..., constrain="nodes")``: the constraint at every dof of W^h on the constrained
boundary, against closed forms:

* the block's bottom y = 0 with nx squares of width h carries 2 nx + 1 P2 nodes at x = k h / 2,
  every one constrained (bound -y = 0), the nx + 1 vertices among them;
* the lumped measures are the row sums of the bottom's P2 mass: h/6 per edge at a vertex, 2h/3 at a
  mid-edge node, summing to the width; where those vanish (a domain measure on P2 triangles: 0 at
  the vertices) the HRZ lumping: |T|/19 per triangle at a vertex, 16|T|/57 at an edge's midpoint,
  summing to the area;
* P1 and P1+ have no other boundary dofs than the vertices: refused in one line;
* with the constraint on U^{n+1} (backward Euler) no bottom dof goes below the foundation, while with
  the vertex constraint the mid-edge nodes do (the issue's observation);
* the inspector measures condition (7) with the constraint at every node and reports it honestly:
  the same beta on its dense and iterative paths, named in its report.
"""
from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh as dmesh

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.gaps import boundary_gap
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.mpiutil import gather_rows
from sdm_dolfinx.analysis import inspect, report
from sdm_dolfinx.analysis.infsup import TOL
from sdm_dolfinx.problems import Problem, block

COMM = MPI.COMM_WORLD
W_, H_, NX, NY = 20.0, 10.0, 10, 5
STEP = W_ / NX


def the_block(comm=COMM, **kw):
    return block.problem(comm, width=W_, height=H_, nx=NX, ny=NY, start="rest", **kw)


def on_rank0(values):
    return gather_rows(np.asarray(values), COMM)


def test_every_bottom_node_is_constrained_with_its_row_sum_measure():
    d = Discretisation(the_block(), "P2/P1", constrain="nodes")
    assert d.num_constraints == 2 * NX + 1
    assert np.all(d.cdofs % 2 == 1) and np.allclose(d.lb, 0.0, rtol=0, atol=1e-14)   # u_y, bound -y = 0
    # (to round-off: the P2 nodes' coordinates carry +-4e-17 with OpenBLAS)
    x, m, vert = on_rank0(d.cx[0]), on_rank0(d.cmeasure), on_rank0(d.c_vertex)
    assert np.array_equal(d.cverts >= 0, d.c_vertex)
    if COMM.rank == 0:
        o = np.argsort(x)
        x, m, vert = x[o], m[o], vert[o]
        assert np.allclose(x, np.arange(2 * NX + 1) * STEP / 2, atol=1e-12)
        assert np.array_equal(vert, np.arange(2 * NX + 1) % 2 == 0)
        expected = np.where(vert, STEP / 3, 2 * STEP / 3)
        expected[[0, -1]] = STEP / 6                                       # the corners: one edge
        assert np.abs(m - expected).max() <= 1e-13 * STEP
        assert abs(m.sum() - W_) <= 1e-12 * W_


def test_vertex_constraint_is_unchanged():
    d = Discretisation(the_block(), "P2/P1")
    assert d.num_constraints == NX + 1 and np.all(d.c_vertex) and np.all(d.cverts >= 0)


def domain_problem(n=3):
    """A scalar problem on the unit square with every vertex constrained and the domain measure
    q dx (the membrane's kind), no Dirichlet data: P2's vertex row sums vanish there."""
    msh = dmesh.create_unit_square(COMM, n, n)
    nv = lambda m: m.topology.index_map(0).size_local + m.topology.index_map(0).num_ghosts   # noqa: E731
    return Problem(name="square", mesh=msh, shape=(),
                   a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx, l=lambda w: w * ufl.dx,
                   u0=lambda x: np.zeros(x.shape[1]), v0=lambda x: np.zeros(x.shape[1]),
                   constraint_vertices=lambda m: np.arange(nv(m), dtype=np.int32),
                   lower_bound=lambda x: -np.ones(x.shape[1]), constraint_measure=lambda q: q * ufl.dx)


def test_vanishing_row_sums_fall_back_to_hrz():
    n = 3
    d = Discretisation(domain_problem(n), "P2/P1", constrain="nodes")
    area_T = 1.0 / (2 * n * n)
    x, m, vert = on_rank0(d.cx[:2].T), on_rank0(d.cmeasure), on_rank0(d.c_vertex)
    assert d.num_constraints == (2 * n + 1) ** 2                          # every P2 node of the square
    if COMM.rank == 0:
        assert np.all(m > 0) and abs(m.sum() - 1.0) <= 1e-12
        # 'right' diagonals: an interior vertex lies in 6 triangles, an interior edge's midpoint in 2
        inner = np.all((x > 1e-9) & (x < 1 - 1e-9), axis=1)
        assert np.allclose(m[vert & inner], 6 * area_T / 19, rtol=1e-12)
        assert np.allclose(m[~vert & inner], 2 * 16 * area_T / 57, rtol=1e-12)


@pytest.mark.parametrize("pair", ["P1/P1", "P1+/P0", "P1/P0"])
def test_nodes_with_vertex_only_boundaries_is_refused(pair):
    with pytest.raises(DiscretisationError) as e:
        Discretisation(the_block(), pair, constrain="nodes")
    assert "\n" not in str(e.value) and pair in str(e.value) and "constrain='vertices'" in str(e.value)


def test_unknown_constrain_is_refused():
    with pytest.raises(ValueError) as e:
        Discretisation(the_block(), "P2/P1", constrain="edges")
    assert "vertices" in str(e.value) and "nodes" in str(e.value)


def dropped(constrain, steps=60, dt=1e-5, vy=-2000.0):
    """The block dropped at 2 m/s onto y = 0, backward Euler (constraint on U^{n+1}): the lowest
    bottom dof over the steps (mid-edge nodes included) and the largest multiplier."""
    p = the_block()
    p.v0 = lambda x: np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], vy)])
    d = Discretisation(p, "P2/P1", constrain=constrain)
    integ = Integrator(d, "backward-euler", dt)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    gaps, lam = [], 0.0
    for n in range(steps):
        integ.step(U, V, n, n * dt)
        gaps.append(boundary_gap(integ.discretisation, U.array_r))
        lam = max(lam, COMM.allreduce(float(np.max(integ.lam, initial=0.0)), op=MPI.MAX))
    integ.destroy()
    return min(gaps), lam


def test_nodes_keep_mid_edge_nodes_above_the_foundation():
    vertices, lam_v = dropped("vertices")
    nodes, lam_n = dropped("nodes")
    assert lam_v > 0 and lam_n > 0                                          # contact happened
    assert vertices < -1e-3 * STEP                                          # the mid-edge nodes sink
    assert nodes >= -1e-12 * STEP


def test_inspect_reports_p2_p1_with_the_constraint_at_every_node():
    p = the_block()
    dense = inspect(p, "P2/P1", constrain="nodes")
    iterative = inspect(p, "P2/P1", constrain="nodes", dense_max=0)
    assert dense["N_g"] == 2 * NX + 1 and dense["constrain"] == "nodes"
    assert dense["method_short"] == "dense" and iterative["method_short"] == "iterative"
    assert abs(dense["beta"] - iterative["beta"]) <= 1e-8
    assert dense["verdict"] == ("well-posed" if dense["beta"] > TOL else "ill-posed")
    text = report(dense)
    assert "every dof of W^h on the constrained boundary" in text and f"{dense['beta']:.6g}" in text
    assert dense["verdict"].upper() in text
    # the vertex constraint is a subset of the node constraint: its beta is at least as large
    assert inspect(p, "P2/P1")["beta"] >= dense["beta"] - 1e-12
