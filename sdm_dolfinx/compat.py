"""Everything that differs between dolfinx 0.5 (Debian 12) and dolfinx >= 0.7 (0.9/0.10).

Only this module may look at ``dolfinx.__version__``; the rest of the package calls
these helpers, so a port to a new dolfinx touches this file alone.
"""
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import numpy as np
import ufl
from dolfinx import fem, geometry

DOLFINX_VERSION = tuple(int(p) for p in dolfinx.__version__.split(".")[:2])
NEW_API = DOLFINX_VERSION >= (0, 7)

if NEW_API:  # pragma: no cover - exercised only on dolfinx >= 0.7
    import basix.ufl


def element(family, cell, degree, shape=()):
    """A Lagrange-type (or DG, Bubble) element, scalar or with value ``shape``."""
    if NEW_API:  # pragma: no cover
        return basix.ufl.element(family, cell, degree, shape=shape if shape else None)
    if shape:
        return ufl.VectorElement(family, cell, degree, dim=shape[0])
    return ufl.FiniteElement(family, cell, degree)


def p1_bubble_element(cell, shape=()):
    """P1 enriched with the cubic bubble (the paper's P1+)."""
    if NEW_API:  # pragma: no cover
        e = basix.ufl.enriched_element([basix.ufl.element("Lagrange", cell, 1),
                                        basix.ufl.element("Bubble", cell, 3)])
        return basix.ufl.blocked_element(e, shape=shape) if shape else e
    e = ufl.FiniteElement("Lagrange", cell, 1) + ufl.FiniteElement("Bubble", cell, 3)
    if shape:
        return ufl.VectorElement(e, dim=shape[0])
    return e


def cell_name(msh):
    """The cell name ('triangle', ...) of a mesh, as element constructors want it."""
    if NEW_API:  # pragma: no cover
        return msh.topology.cell_name()
    return msh.ufl_cell().cellname()


def function_space(msh, elem):
    if NEW_API:  # pragma: no cover
        return fem.functionspace(msh, elem)
    return fem.FunctionSpace(msh, elem)


def petsc_vec(f):
    """The PETSc vector wrapping a Function's dof array (owned + ghosts)."""
    if NEW_API:  # pragma: no cover
        return f.x.petsc_vec
    return f.vector


def form(expr, jit_options=None):
    if NEW_API:  # pragma: no cover
        return fem.form(expr, jit_options=jit_options)
    return fem.form(expr, jit_params=jit_options)


def petsc_module():
    """``dolfinx.fem.petsc`` (assemble_matrix, assemble_vector, ...)."""
    import dolfinx.fem.petsc
    return dolfinx.fem.petsc


def assemble_matrix(a, bcs=(), diagonal=1.0):
    A = petsc_module().assemble_matrix(a, list(bcs), diagonal)
    A.assemble()
    return A


def assemble_vector(L):
    b = petsc_module().assemble_vector(L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def assemble_matrix_block(a, bcs=(), diagonal=1.0):
    A = petsc_module().assemble_matrix_block(a, list(bcs), diagonal)
    A.assemble()
    return A


def model_to_mesh(model, comm, rank, gdim):
    """gmsh model -> (mesh, cell_tags, facet_tags)."""
    if NEW_API:  # pragma: no cover
        from dolfinx.io import gmshio
        data = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
        return data[0], data[1], data[2]
    from dolfinx.io import gmshio
    msh, ct, ft = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
    return msh, ct, ft


def bounding_box_tree(msh):
    if NEW_API:  # pragma: no cover
        return geometry.bb_tree(msh, msh.topology.dim)
    return geometry.BoundingBoxTree(msh, msh.topology.dim)


def colliding_cells(msh, tree, points):
    """For each point (rows of an (n, 3) array), the local cells containing it."""
    if NEW_API:  # pragma: no cover
        cand = geometry.compute_collisions_points(tree, points)
    else:
        cand = geometry.compute_collisions(tree, points)
    return geometry.compute_colliding_cells(msh, cand, points)


def mesh_geometry_dofmap(msh):
    """Cell -> geometry node indices, as a 2-D array."""
    if NEW_API:  # pragma: no cover
        return msh.geometry.dofmap
    return msh.geometry.dofmap.array.reshape(msh.topology.index_map(msh.topology.dim).size_local
                                             + msh.topology.index_map(msh.topology.dim).num_ghosts, -1)


def entities_to_geometry(msh, dim, entities):
    """Geometry node indices of mesh entities."""
    if NEW_API:  # pragma: no cover
        from dolfinx import mesh as dmesh
        return dmesh.entities_to_geometry(msh, dim, entities, False)
    from dolfinx import cpp
    return cpp.mesh.entities_to_geometry(getattr(msh, "_mesh", msh), dim, entities, False)


def xdmf_file(comm, path, mode="w"):
    from dolfinx import io
    return io.XDMFFile(comm, str(path), mode)


def versions():
    """Library versions for run.json."""
    import basix
    import petsc4py
    return {"dolfinx": dolfinx.__version__, "basix": basix.__version__, "ufl": ufl.__version__,
            "petsc4py": petsc4py.__version__, "petsc": ".".join(map(str, PETSc.Sys.getVersion())),
            "mpi4py": __import__("mpi4py").__version__, "numpy": np.__version__,
            "mpi": MPI.Get_library_version().splitlines()[0]}
