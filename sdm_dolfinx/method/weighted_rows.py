"""The weighted (mortar) gap: ``constrain="weighted"``, rows that hold a contact face between its vertices.

With the vertex constraint (13) a P2 face is held at its vertices only, and its mid-edge nodes sink
below the obstacle (an O(h) error: docs/contact.md). The weighted gap constrains, at each
constrained vertex a_i, the gap averaged against the contact boundary's P1 hat function psi_i:

    G_i u = int_Gamma_C psi_i u_c ds / int_Gamma_C psi_i ds  >=  int_Gamma_C psi_i g ds / int_Gamma_C psi_i ds,

Gamma_C the contact boundary (the exterior facets whose vertices are all constrained). Row i reads
every dof of W^h on the facets around a_i (vertices and P2 mid-edge nodes: a row may read dofs of
another rank). Dividing by int psi_i ds makes G_i an average, so that the row's multiplier lam_i is a
nodal force like the vertex constraint's (the force on the body is G^T lam, and sum_i lam_i its total):
``contact_force``, the stresses lam_i / measure_i and every column keep their meaning. A linear field
u_c that meets a linear bound g on the face satisfies every row exactly, so the contact patch test
(a face pushed uniformly onto a plane) holds on P2 where the vertex constraint lets the face sink.
The bound is the interpolant of ``lower_bound`` in W^h (exact for a plane). For W^h without dofs on
the facets but at vertices (P1, P1+), G is the normalised boundary mass matrix (a mortar constraint
that differs from the vertex one); in 1-D the boundary is a point and the rows are the vertex
constraint's (refused: it would change nothing).

Dirichlet dofs on the face (constant data): their columns leave G and their known values the right-
hand side g (a Dirichlet part there prescribes the constrained component at the face's vertices too,
which :mod:`.dirichlet` refuses). Not yet: obstacles, a moving bound (refused in one line).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl

from sdm_dolfinx import compat
from sdm_dolfinx.method import problem_data
from sdm_dolfinx.method.contact_boundary import contact_facets, contact_measure
from sdm_dolfinx.method.dofs import owned_size
from sdm_dolfinx.method.errors import DiscretisationError


#: the quadrature degree of the rows' boundary integrals (psi_i phi_j: degree 3 for P2 on straight facets)
QUADRATURE_DEGREE = 4


class WeightedRows:
    """The rows of ``constrain="weighted"`` of a Discretisation ``d`` (see the module).

    Attributes:
        G: the PETSc matrix of the rows (this rank's constrained vertices, in ``d.cdofs``'s order; W's
            column layout, Dirichlet columns zero).
        g: their right-hand sides (this rank's rows).
    """

    def __init__(self, d):
        p, msh, comm = d.problem, d.problem.mesh, d.comm
        name = f"problem {p.name!r}"
        if msh.topology.dim == 1:
            raise DiscretisationError(f"constrain='weighted' is constrain='vertices' in 1-D (the contact boundary is a "
                                      f"point); use constrain='vertices'")
        if getattr(p, "obstacles", ()) or getattr(p, "moving_bound", False):
            raise DiscretisationError(f"{name}: constrain='weighted' against obstacles or a moving bound is not built "
                                      f"yet: use constrain='vertices' or 'nodes'")
        facets = contact_facets(d)
        ds = contact_measure(d, facets, QUADRATURE_DEGREE)
        q, u = ufl.TestFunction(d.Q1), ufl.TrialFunction(d.W)
        c = p.constraint_component or 0
        uc = u[c] if p.shape else u
        full = compat.assemble_matrix(d.form(ufl.inner(uc, q) * ds))
        weight = compat.assemble_vector(d.form(q * ds))          # ghost contributions added to their owners
        weight.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        q1_owned = d.Q1.dofmap.index_map.size_local
        rows_local = np.asarray(d.q1_of_c, dtype=np.int64)
        with weight.localForm() as wl:
            w = wl.array_r[rows_local].copy() if rows_local.size else np.zeros(0)
        wrong = None
        if np.any(rows_local >= q1_owned):
            wrong = "a constrained vertex's P1 dof is owned by another rank than its W^h dof"
        elif np.any(w <= 0.0):
            wrong = (f"{int(np.sum(w <= 0))} constrained vertices are on no contact facet (a facet whose vertices "
                     f"are all constrained), where the weighted gap integrates")
        found = [m for m in comm.allgather(wrong) if m]
        if found:
            raise DiscretisationError(f"{name}: constrain='weighted': {found[0]}; use constrain='vertices'")
        q0 = d.Q1.dofmap.index_map.local_range[0]
        isrow = PETSc.IS().createGeneral((q0 + rows_local).astype(PETSc.IntType), comm=comm)
        w0, nw = d.W.dofmap.index_map.local_range[0] * d.W.dofmap.index_map_bs, owned_size(d.W)
        iscol = PETSc.IS().createStride(nw, w0, 1, comm=comm)
        G = full.createSubMatrix(isrow, iscol)
        full.destroy(), isrow.destroy(), iscol.destroy()
        inv = G.createVecLeft()
        inv.array[:] = 1.0 / w
        G.diagonalScale(L=inv)                      # each row an average: its multiplier a nodal force
        # the bound: lower_bound interpolated in W^h's component c (its dofs' coordinates)
        bound = G.createVecRight()
        x = d._dof_x()[:nw // max(d.W.dofmap.index_map_bs, 1)].T
        bs = d.W.dofmap.index_map_bs
        bound.array[c::bs] = problem_data.bound(p, x, comm) if x.shape[1] else np.zeros(0)
        fixed = np.asarray(d.ddofs, dtype=np.int64)
        if fixed.size:      # Dirichlet dofs: G_i u = G_free u + G_D u_D >= G_i g
            bound.array[fixed] -= d.g.x.array[fixed]
        gvec = G.createVecLeft()
        G.mult(bound, gvec)
        keep = G.createVecRight()
        keep.set(1.0)
        keep.array[fixed] = 0.0
        G.diagonalScale(R=keep)
        self.G, self.g = G, gvec.array_r.copy()
        for v in (inv, bound, gvec, keep):
            v.destroy()
