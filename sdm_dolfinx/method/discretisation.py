"""Problem + Pair -> matrices: A, L, the singular mass M = B^T C^-1 B (or B and C), bounds.

Notation of the paper, section 2: W^h (basis phi_i) carries the displacement, H^h (basis
psi_i) the velocity; B_ij = (psi_i, phi_j), C_ij = (psi_i, psi_j), M = B^T C^-1 B. All
mass-type forms carry the density rho.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.dofs import owned_size as owned_size, vertex_coordinates as vertex_coordinates  # noqa: F401
from sdm_dolfinx.method.dofs import vertex_to_dof as vertex_to_dof
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.frozen import FrozenData
from sdm_dolfinx.method import dirichlet as _parts, equilibrium, masses, problem_data, quadrature
from sdm_dolfinx.method.body_rows import BodyRows
from sdm_dolfinx.method.weighted_body_rows import WeightedBodyRows
from sdm_dolfinx.method.obstacle_rows import ObstacleRows
from sdm_dolfinx.method.weighted_rows import WeightedRows
from sdm_dolfinx.problems import density
from sdm_dolfinx.method.pairs import MASS_TREATMENTS, get_pair

#: an initial displacement below the bound by more than this times max(1, max |bound|) at a
#: constrained vertex is refused (the scale of simulate's constraint_tol)
INITIAL_TOL = 1e-8
#: where K^h acts: at the constrained vertices (eq. (13)), or at every dof of W^h on the
#: constrained boundary (P2's mid-edge nodes too)
CONSTRAIN = ("vertices", "nodes", "weighted")


class Discretisation:
    """The space semi-discretisation (paper eq. (3)–(5)) of a Problem with a Pair.

    Args:
        problem: a :class:`sdm_dolfinx.problem.Problem`.
        pair: a pair name (``"P2/P1"``) or :class:`sdm_dolfinx.pairs.Pair`.
        mass: how C is treated: ``"diagonal"`` (P0: exact), ``"lumped"`` (P1, row sums),
            ``"consistent"`` (P1: the (U, V) block system, M never formed); for a standard pair
            (H^h = W^h) its consistent mass ``"standard"``, the row-sum lumped ``"row-sum"`` or
            Khenous-Laborde-Renard's ``"redistributed"`` (no inertia at the constrained nodes,
            :mod:`.masses`). ``None`` picks the pair's default.
        quadrature_degree: the quadrature degree of every form (A, L, B, C, M, the lumped
            measure): None (automatic: UFL's exact estimate on affine simplices, 12 on curved
            cells, see :mod:`.quadrature`), ``"estimated"`` (UFL's estimate everywhere: runs
            before the option) or an integer; the value used is :attr:`quadrature_degree`.
        constrain: ``"vertices"`` (eq. (13): K^h acts at the constrained vertices) or ``"nodes"``
            (at every dof of W^h on the constrained boundary, :meth:`_boundary`: P2's mid-edge
            nodes too; each node's stress measure is then the boundary's row sum in W^h,
            :func:`.masses.nodal_measure`). ``"nodes"`` is refused where it names the vertices
            only (P1, P1+, and every pair in 1-D, whose boundary is a vertex). ``"weighted"``: one
            row per constrained vertex, the gap averaged over the contact facets around it
            against its P1 hat function (:mod:`.weighted_rows`: holds a P2 face between vertices;
            between bodies, the node-to-surface gap of every slave node so averaged:
            :mod:`.weighted_body_rows`).

    Raises:
        ProblemInputError: the Problem's own validation (:meth:`Problem.validate`).
        DiscretisationError: the pair has no element on the mesh's cell type; ``constrain="nodes"``
            where it is "vertices"; a modified mass the pair or mesh cannot have (:mod:`.masses`).
    """

    def __init__(self, problem, pair, mass=None, quadrature_degree=None, constrain="vertices"):
        problem.validate()          # a field may have been changed since the Problem was made
        bad = quadrature.check(quadrature_degree)
        if bad:
            raise ValueError(bad[0])
        if constrain not in CONSTRAIN:
            raise ValueError(f"constrain must be one of {', '.join(CONSTRAIN)} (got {constrain!r})")
        if problem.contact_pairs and constrain == "nodes":
            raise DiscretisationError(f"problem {problem.name!r} has contact pairs, which constrain {constrain!r} does "
                                      f"not take yet: use constrain 'vertices' or 'weighted'")
        self.constrain = constrain
        self.problem = problem
        self.pair = get_pair(pair) if isinstance(pair, str) else pair
        self.mass = mass or self.pair.default_mass()
        if self.mass not in MASS_TREATMENTS or self.mass not in self.pair.allowed_masses():
            raise ValueError(f"mass treatment {self.mass!r} is not available for pair {self.pair.name}; "
                             f"choose one of {', '.join(self.pair.allowed_masses())}")
        msh = problem.mesh
        self.comm = msh.comm
        cell = compat.cell_name(msh)
        shape = tuple(problem.shape)
        self.W = compat.function_space(msh, self.pair.w_element(cell, shape))
        self.H = (None if self.pair.standard
                  else compat.function_space(msh, self.pair.h_element(cell, shape)))
        # P1 spaces for output (XDMF wants vertex fields) and nodal measures
        self.Q1 = compat.function_space(msh, compat.element("Lagrange", cell, 1))
        self.P1 = (self.Q1 if not shape else compat.function_space(msh, compat.element("Lagrange", cell, 1, shape)))
        self._mass = self._M = None
        self._M_deferred = False
        self._assemble(quadrature_degree)
        self._constraints()
        self._dirichlet()
        self._boundary()
        self.c_vertex = np.ones(len(self.cdofs), dtype=bool)      # which constrained dofs are vertex dofs
        if constrain == "nodes":
            self._nodes()
        #: the gap rows against the Problem's rigid obstacles (:mod:`.obstacle_rows`), or None
        self.obstacle_rows = ObstacleRows(self) if problem.obstacles else None
        #: the gap rows between the bodies of the Problem's contact pairs (:mod:`.body_rows`), or None
        self.body_rows = ((WeightedBodyRows if constrain == "weighted" else BodyRows)(self) if problem.contact_pairs
                          else None)
        #: the weighted gap's rows (constrain="weighted": :mod:`.weighted_rows`), or None
        self.weighted_rows = (WeightedRows(self) if constrain == "weighted" and self.num_constraints
                              and self.body_rows is None else None)
        if self.mass in masses.MODIFIED:
            consistent, self.M = self.M, masses.build(self)
            consistent.destroy()
        self.frozen = FrozenData(problem, self._a_ufl, self._l_ufl, self.cx if self.num_constraints else None,
                                 self._dirichlet_x(), self.comm)

    # ------------------------------------------------------------------ matrices
    def _assemble(self, quadrature_degree):
        p = self.problem
        u, w = ufl.TrialFunction(self.W), ufl.TestFunction(self.W)
        rho = density.form(p)
        self._a_ufl, self._l_ufl = p.a(u, w), p.l(w)
        if self.pair.standard:                  # the consistent mass (modified after the constraints)
            mass = {"M": rho * ufl.inner(u, w) * ufl.dx}
        else:
            q, r = ufl.TestFunction(self.H), ufl.TrialFunction(self.H)
            mass = {"B": rho * ufl.inner(u, q) * ufl.dx, "C": rho * ufl.inner(r, q) * ufl.dx}   # N_H x N_W, N_H x N_H
        self._measure_ufl = p.constraint_measure(ufl.TestFunction(self.Q1))
        #: the quadrature degree of every form: an integer, or "estimated" (UFL's estimate of each)
        self.quadrature_degree = quadrature.effective(
            quadrature_degree, p.mesh, [self._a_ufl, self._l_ufl, self._measure_ufl, *mass.values()])
        self.A = compat.assemble_matrix(self.form(self._a_ufl))
        self.L_form = self.form(self._l_ufl)
        if p.time is not None:
            p.time.value = 0.0
        self.L = compat.assemble_vector(self.L_form)       # L(0) for a time-dependent load
        self.B = self.C = self.c_lumped = self.M = None
        for name, m in mass.items():
            setattr(self, name, compat.assemble_matrix(self.form(m)))
        if self.pair.standard or self.mass == "consistent":
            return               # consistent: M never formed, the integrator solves the (U, V) block system
        # C diagonal: exact for P0 (C is diagonal), row-sum lumping for P1
        ones = self.C.createVecRight()
        ones.set(1.0)
        self.c_lumped = self.C.createVecLeft()
        self.C.mult(ones, self.c_lumped)
        self._M_deferred = True                   # M = B^T C^-1 B formed when first asked for (:attr:`M`)

    @property
    def M(self):
        """The mass matrix of W^h: M = B^T C^-1 B for a pair with a diagonal C (formed when first asked
        for: a run whose step operator is matrix-free, :mod:`.matrix_free`, never forms it), the consistent
        or modified mass of a standard pair, or None (mass ``"consistent"``: never formed)."""
        if self._M is None and self._M_deferred:
            self._M, self._M_deferred = masses.singular(self.B, self.c_lumped), False
        return self._M

    @M.setter
    def M(self, value):
        self._M = value

    @property
    def mass_formed(self):
        """Whether :attr:`M` is held as a matrix now (False: not formed yet, or never)."""
        return self._M is not None

    def form(self, expr):
        """The compiled form of the UFL ``expr`` at this discretisation's quadrature degree
        (for every form assembled with its matrices: the integrator's block system, a
        recomputed energy)."""
        return compat.form(expr, quadrature_degree=quadrature.compiler_degree(self.quadrature_degree))

    def load(self, t, out):
        """Reassemble L at time ``t`` into ``out`` (a Problem declaring ``time``); returns ``out``."""
        self.problem.time.value = t
        return compat.assemble_vector_into(out, self.L_form)

    def mass_product(self):
        """The fastest ``mult(x, y)``: y = M x for this discretisation (:func:`.masses.product`)."""
        return masses.product(self)

    def mass_mult(self, x, y):
        """y = M x (also for the consistent variant, through a solve with C)."""
        if self._mass is None:
            self._mass = self.mass_product()
        self._mass(x, y)

    def _consistent_mass_mult(self, x, y):
        bx = self.B.createVecLeft()
        self.B.mult(x, bx)
        z = self.solve_C(bx)
        self.B.multTranspose(z, y)

    def physical_velocity(self, Vbar: PETSc.Vec, out: PETSc.Vec) -> PETSc.Vec:
        """out = C^-1 B Vbar, the velocity in H^h of the M formulation (C diagonal: exact for P0,
        lumped for P1, as M = B^T C^-1 B is built); returns ``out`` (a vector of H^h)."""
        self.B.mult(Vbar, out)
        out.pointwiseDivide(out, self.c_lumped)
        return out

    def solve_C(self, b):
        """C^-1 b with CG (C is a well-conditioned mass matrix)."""
        if not hasattr(self, "_ksp_C"):
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOperators(self.C)
            ksp.setType("cg")
            ksp.getPC().setType("jacobi")
            ksp.setTolerances(rtol=1e-14, atol=1e-300, max_it=1000)
            self._ksp_C = ksp
        x = self.C.createVecRight()
        self._ksp_C.solve(b, x)
        if self._ksp_C.getConvergedReason() <= 0:
            raise RuntimeError(f"solve with C failed (reason {self._ksp_C.getConvergedReason()})")
        return x

    # --------------------------------------------------------------- constraints
    def _owned_constrained_vertices(self, verts):
        """The owned vertices that any rank's ``constraint_vertices`` named (owned or ghost).

        ``locate_entities_boundary`` finds a boundary vertex only on the ranks holding one of
        its boundary facets, which need not include its owner: a flag on a P1 function, added
        into the owners, makes the constrained set independent of the partition.
        """
        msh = self.problem.mesh
        nloc = msh.topology.index_map(0).size_local
        nall = nloc + msh.topology.index_map(0).num_ghosts
        flag = fem.Function(self.Q1)
        v2d = vertex_to_dof(self.Q1, np.arange(nall, dtype=np.int32))
        if verts.size:
            flag.x.array[v2d[verts]] = 1.0
        vec = compat.petsc_vec(flag)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        marked = flag.x.array[v2d] > 0                        # per local vertex, owned and ghost
        self._verts_local = np.flatnonzero(marked).astype(np.int32)   # for the constrained facets
        return np.flatnonzero(marked[:nloc]).astype(np.int32)

    def _constraints(self):
        """Owned constrained dofs of W (vertex dofs only, eq. (13)) and their lower bounds."""
        p = self.problem
        msh = p.mesh
        verts = self._owned_constrained_vertices(problem_data.vertices(p, self.comm))
        bs = self.W.dofmap.index_map_bs
        comp = p.constraint_component or 0                  # validated: None only for a scalar u
        dofs = vertex_to_dof(self.W, verts) * bs + comp
        keep = dofs < owned_size(self.W)
        # a vertex owned here whose dof is owned elsewhere is constrained by that rank
        verts_all = verts
        verts, dofs = verts_all[keep], dofs[keep]
        order = np.argsort(dofs)
        self.cverts, self.cdofs = verts[order], dofs[order].astype(np.int32)
        self.cx = xv = vertex_coordinates(msh, self.cverts) if self.cverts.size else np.zeros((3, 0))
        self.lb = problem_data.bound(p, xv, self.comm)
        self.num_constraints = self.comm.allreduce(len(self.cdofs), op=MPI.SUM)
        # lumped nodal measure at each constrained vertex (for stress = multiplier / measure)
        m = compat.assemble_vector(self.form(self._measure_ufl))
        m.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with m.localForm() as ml:
            meas = ml.array_r[vertex_to_dof(self.Q1, self.cverts)] if self.cverts.size else np.zeros(0)
        self.cmeasure = np.array(meas)
        self.q1_of_c = vertex_to_dof(self.Q1, self.cverts)

    def _dirichlet(self):
        """``ddofs`` (the owned Dirichlet dofs), ``g`` (their values at t = 0) and the Dirichlet parts'
        dofs (:func:`.dirichlet.setup`); a Dirichlet dof leaves the constraint set."""
        _parts.setup(self)

    def part_values(self, k, t, rate=False):
        """The data of Dirichlet part ``k`` at time ``t`` (``rate``: its velocity) at its owned dofs
        ``part_dofs[k]`` (collective; :func:`.dirichlet.part_values`)."""
        return _parts.part_values(self, k, t, rate)

    def _boundary(self):
        """Owned dofs of W^h (the bounded component) on the constrained boundary -- the facets whose
        vertices are all constrained -- with their coordinates and the bound there: P2's mid-edge
        nodes, which the vertex constraint (13) does not hold, are among them."""
        p, W, msh = self.problem, self.W, self.problem.mesh
        tdim, fdim = msh.topology.dim, msh.topology.dim - 1
        mark = fem.Function(self.Q1)                        # 1 at constrained vertices, consistent on ghosts
        verts = self._verts_local
        if verts.size:
            mark.x.array[vertex_to_dof(self.Q1, verts)] = 1.0
        vec = compat.petsc_vec(mark)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        msh.topology.create_connectivity(fdim, 0)
        msh.topology.create_connectivity(fdim, tdim)
        nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
        v2q = vertex_to_dof(self.Q1, np.arange(nv))
        fv = msh.topology.connectivity(fdim, 0).array.reshape(-1, tdim)   # a simplex facet has tdim vertices
        facets = np.flatnonzero(np.all(mark.x.array[v2q[fv]] > 0, axis=1)).astype(np.int32)
        blocks = fem.locate_dofs_topological(W, fdim, facets)
        bs = W.dofmap.index_map_bs
        dofs = blocks.astype(np.int64) * bs + (p.constraint_component or 0)
        keep = (dofs < owned_size(W)) & ~np.isin(dofs, self.ddofs)
        order = np.argsort(dofs[keep])
        self.bdofs = dofs[keep][order].astype(np.int32)
        self.bx = self._dof_x()[blocks[keep][order]].T if self.bdofs.size else np.zeros((3, 0))
        self.blb = problem_data.bound(p, self.bx, self.comm)
        self.num_boundary_dofs = self.comm.allreduce(len(self.bdofs), op=MPI.SUM)

    def _nodes(self):
        """constrain="nodes": K^h at every dof of :meth:`_boundary` too (P2's mid-edge nodes), each with
        its bound at the node and the boundary's measure lumped in W^h (:func:`.masses.nodal_measure`);
        ``cverts`` is -1 and ``c_vertex`` False at a dof that is not a vertex's; ``q1_of_c`` keeps the Q1 dofs
        of the vertex ones (``values[c_vertex]`` go there)."""
        W, msh = self.W, self.problem.mesh
        if not any(compat.num_entity_dofs(W, k) for k in range(1, msh.topology.dim)):
            raise DiscretisationError(
                f"constrain='nodes' is constrain='vertices' for pair {self.pair.name} on {compat.cell_name(msh)} "
                f"meshes: W^h has no dof on the constrained boundary but at its vertices; use constrain='vertices'")
        dofs = np.union1d(self.cdofs, self.bdofs).astype(np.int32)
        self.c_vertex = np.isin(dofs, self.cdofs)             # both sorted: the vertex dofs in cdofs' order
        verts = np.full(len(dofs), -1, dtype=np.int32)
        verts[self.c_vertex] = self.cverts
        self.cdofs, self.cverts = dofs, verts
        self.cx = self._dof_x()[dofs // W.dofmap.index_map_bs].T if dofs.size else np.zeros((3, 0))
        self.lb = problem_data.bound(self.problem, self.cx, self.comm)
        self.cmeasure = masses.nodal_measure(self, dofs)
        self.num_constraints = self.comm.allreduce(len(dofs), op=MPI.SUM)

    def _dirichlet_x(self):
        """Coordinates (3, n) of the owned dofs of ``dirichlet_facets`` (None without them; the
        Dirichlet parts are evaluated at every step)."""
        if self.problem.dirichlet_facets is None:
            return None
        bs = self.W.dofmap.index_map_bs
        return self._dof_x()[np.unique(self._fixed_ddofs // bs)].T

    def _dof_x(self):
        """W's dof coordinates (blocks, owned and ghost), tabulated once."""
        if getattr(self, "_dof_coords", None) is None:
            self._dof_coords = self.W.tabulate_dof_coordinates()
        return self._dof_coords

    # ------------------------------------------------------------------ helpers
    def dims(self):
        """Global dimensions: dim W^h, dim H^h, N_g."""
        W = self.W
        nW = W.dofmap.index_map.size_global * W.dofmap.index_map_bs
        nH = (nW if self.H is None else self.H.dofmap.index_map.size_global * self.H.dofmap.index_map_bs)
        return {"dim_W": int(nW), "dim_H": int(nH), "N_g": int(self.num_constraints)}

    def initial_state(self, friction=None, contact="exact"):
        """(U0, Vbar0): u0 (:func:`.equilibrium.initial_displacement`) and v0 in W, Dirichlet values imposed."""
        p = self.problem
        u0, v0 = fem.Function(self.W), fem.Function(self.W)
        equilibrium.initial_displacement(self, u0, friction, contact)
        v0.interpolate(p.v0)
        U, V = compat.petsc_vec(u0).copy(), compat.petsc_vec(v0).copy()
        problem_data.initial_finite(p, U, V, self.comm)
        if self.ddofs.size:
            U.array[self.ddofs] = self.g.x.array[self.ddofs]
            V.array[self._fixed_ddofs] = 0.0
        for k, dofs in enumerate(self.part_dofs):       # a part's data may not start at rest (collective)
            V.array[dofs] = self.part_values(k, 0.0, rate=True)
        self._check_initial(U)
        return U, V

    def _check_initial(self, U):
        """DiscretisationError when U0 is below the bound at constrained vertices (beyond INITIAL_TOL)."""
        comm = self.comm
        rows = self.obstacle_rows if self.obstacle_rows is not None else self.body_rows
        if rows is not None:
            gap, scale = rows.phi(U.array_r, 0.0), rows.size
        elif self.weighted_rows is not None:            # the rows G U >= g, one per constrained vertex
            Gu = self.weighted_rows.G.createVecLeft()
            self.weighted_rows.G.mult(U, Gu)
            gap, scale = Gu.array_r - self.weighted_rows.g, None
            Gu.destroy()
        else:
            gap = U.array[self.cdofs] - self.lb
            scale = None
        scale = scale or max(comm.allreduce(float(np.max(np.abs(self.lb), initial=0.0)), op=MPI.MAX), 1.0)
        tol = INITIAL_TOL * scale
        count = comm.allreduce(int(np.sum(gap < -tol)), op=MPI.SUM)
        if not count:
            return
        k = int(np.argmin(gap)) if gap.size else -1
        worst, owner = comm.allreduce((float(gap[k]) if k >= 0 else np.inf, comm.rank), op=MPI.MINLOC)
        x = comm.bcast(self.cx[:, k] if comm.rank == owner else None, root=owner)
        where = ", ".join(f"{c:.6g}" for c in x[:self.problem.mesh.geometry.dim])
        where_to = ("inside an obstacle" if self.obstacle_rows is not None else "inside a master body"
                    if self.body_rows is not None else "below the bound")
        raise DiscretisationError(
            f"problem {self.problem.name!r}: the initial displacement is {where_to} at {count} constrained "
            f"{'nodes' if self.constrain == 'nodes' else 'vertices'}, by up to {-worst:.3g} at ({where}) (tolerance "
            f"{tol:.1e}); u0 must satisfy the constraint"
            + {"vertices": "", "nodes": " at every constrained node (constrain nodes)",
               "weighted": " averaged around every constrained vertex (constrain weighted)"}[self.constrain])

    def rigid_vector(self, component):
        """The vector of W that represents the constant unit field in ``component``."""
        f = fem.Function(self.W)
        if self.problem.shape:
            n = self.problem.shape[0]
            f.interpolate(lambda x: np.array([np.full(x.shape[1], 1.0 if i == component else 0.0)
                                              for i in range(n)]))
        else:
            f.interpolate(lambda x: np.ones(x.shape[1]))
        return compat.petsc_vec(f).copy()
