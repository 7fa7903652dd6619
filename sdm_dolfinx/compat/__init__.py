"""Everything that differs between dolfinx 0.5 (Debian 12) and dolfinx >= 0.7 (0.9/0.10/0.11),
and between PETSc builds (:mod:`sdm_dolfinx.compat.petsc`, re-exported here).

Only this package may look at ``dolfinx.__version__``; the rest of the package calls
these helpers, so a port to a new dolfinx touches this folder alone.
"""
from pathlib import Path
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx.compat.version import DOLFINX_VERSION, NEW_API

if NEW_API:  # pragma: no cover - exercised only on dolfinx >= 0.7
    import basix.ufl

# re-exported: the rest of the package calls compat.<name>
from sdm_dolfinx.compat.mesh import (bounding_box_tree, cell_candidates, cell_tree, colliding_cells,  # noqa: F401
                                     create_mesh, entities_to_geometry, geometry_degree, mesh_geometry_dofmap,
                                     model_to_mesh)
from sdm_dolfinx.compat.petsc import pc_failed_reason, petsc_has, petsc_options_used  # noqa: F401

#: a finite element: ufl's (dolfinx 0.5) or basix.ufl's (>= 0.7); neither is annotated
Element = Any


def element(family: str, cell: str, degree: int, shape: tuple[int, ...] = ()) -> Element:
    """A Lagrange-type (or DG, Bubble) element, scalar or with value ``shape``."""
    if NEW_API:  # pragma: no cover
        return basix.ufl.element(family, cell, degree, shape=shape if shape else None)
    if shape:
        return ufl.VectorElement(family, cell, degree, dim=shape[0])
    return ufl.FiniteElement(family, cell, degree)


#: the degree of a simplex's bubble (the product of its barycentric coordinates)
BUBBLE_DEGREE = {"interval": 2, "triangle": 3, "tetrahedron": 4}


def p1_bubble_element(cell: str, shape: tuple[int, ...] = ()) -> Element:
    """P1 enriched with the cell's bubble (the paper's P1+: the cubic bubble of a triangle; on an
    interval the quadratic one, basix's "Bubble" of degree 2, so that P1+ spans P2 there; on a
    tetrahedron the quartic one, the lowest basix has)."""
    degree = BUBBLE_DEGREE[cell]
    if NEW_API:  # pragma: no cover
        e = basix.ufl.enriched_element([basix.ufl.element("Lagrange", cell, 1),
                                        basix.ufl.element("Bubble", cell, degree)])
        return basix.ufl.blocked_element(e, shape=shape) if shape else e
    e = ufl.FiniteElement("Lagrange", cell, 1) + ufl.FiniteElement("Bubble", cell, degree)
    if shape:
        return ufl.VectorElement(e, dim=shape[0])
    return e


def cell_name(msh: Any) -> str:
    """The cell name ('triangle', ...) of a mesh, as element constructors want it."""
    if NEW_API:  # pragma: no cover
        return msh.topology.cell_name()
    return msh.ufl_cell().cellname()


def function_space(msh, elem):
    """A function space of ``elem`` on ``msh`` (``FunctionSpace`` in 0.5, ``functionspace`` from 0.7)."""
    if NEW_API:  # pragma: no cover
        return fem.functionspace(msh, elem)
    return fem.FunctionSpace(msh, elem)


def petsc_vec(f):
    """The PETSc vector wrapping a Function's dof array (owned + ghosts)."""
    if NEW_API:  # pragma: no cover
        return f.x.petsc_vec
    return f.vector


def element_degree(V):
    """The polynomial degree of V's element (a method of the UFL element on 0.5, a property of
    basix.ufl's on 0.9)."""
    d = V.ufl_element().degree
    return int(d() if callable(d) else d)


def form(expr, jit_options=None, quadrature_degree=None):
    """``fem.form`` with JIT options (``jit_params`` in 0.5, ``jit_options`` later) and a
    quadrature degree.

    ``quadrature_degree``: None leaves ffcx's choice (UFL's estimated degree); an integer is
    the degree of every integral of ``expr`` (a form, or a list of them, None entries kept)
    whose measure does not set one itself (``ufl.dx(metadata={"quadrature_degree": q})``
    wins, as in ffcx). It goes into each integral's metadata, the one place ffcx reads it in
    0.5 and 0.9 alike: neither has a form-compiler option for it (0.5 accepts
    ``form_compiler_params={"quadrature_degree": q}`` and ignores it: measured, the same matrix
    with q = 1 as with q = 12).
    """
    if quadrature_degree is not None:
        expr = _with_degree(expr, int(quadrature_degree))
    if NEW_API:  # pragma: no cover
        return fem.form(expr, jit_options=jit_options)
    return fem.form(expr, jit_params=jit_options)


def _with_degree(expr, degree):
    """``expr`` (a form, a list of forms or None) with ``degree`` in the metadata of every
    integral that has none."""
    if expr is None:
        return None
    if isinstance(expr, (list, tuple)):
        return [_with_degree(e, degree) for e in expr]
    return ufl.Form([itg if "quadrature_degree" in itg.metadata()
                     else itg.reconstruct(metadata={**itg.metadata(), "quadrature_degree": degree})
                     for itg in expr.integrals()])


def petsc_module():
    """``dolfinx.fem.petsc`` (assemble_matrix, assemble_vector, ...)."""
    import dolfinx.fem.petsc
    return dolfinx.fem.petsc


def assemble_matrix(a, bcs=(), diagonal=1.0):
    """Assemble and finalise the PETSc matrix of the bilinear form ``a`` (``diagonal`` on Dirichlet rows)."""
    A = petsc_module().assemble_matrix(a, list(bcs), diagonal)
    A.assemble()
    return A


def assemble_matrix_baij(a):
    """The matrix of the bilinear form ``a`` in PETSc's block format (BAIJ, the form's block size; no
    Dirichlet rows): ``create_matrix(a, "baij")`` then ``assemble_matrix(A, a)``, the same calls on 0.5.2
    (``mat_type``), 0.9 and 0.11 (``kind``). PETSc's MatConvert from AIJ takes 5.5 s at 107k rows."""
    mod = petsc_module()
    A = mod.create_matrix(a, "baij")
    mod.assemble_matrix(A, a)
    A.assemble()
    return A


def assemble_vector(L):
    """Assemble the PETSc vector of the linear form ``L``, ghost contributions added to their owners."""
    b = petsc_module().assemble_vector(L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def assemble_vector_into(b, L):
    """Reassemble the linear form ``L`` into the existing PETSc vector ``b`` (zeroed first,
    ghost contributions added to their owners): a time-dependent load, every step."""
    with b.localForm() as bl:
        bl.set(0.0)
    petsc_module().assemble_vector(b, L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def assemble_matrix_block(a, bcs=(), diagonal=1.0):
    """One monolithic matrix of the block form ``a`` (list of lists); rows owned by a rank
    are its rows of block 0, then of block 1, ...

    ``assemble_matrix_block`` up to 0.9; 0.10 replaced it by ``assemble_matrix(kind="mpi")``.
    """
    mod = petsc_module()
    if hasattr(mod, "assemble_matrix_block"):
        A = mod.assemble_matrix_block(a, list(bcs), diagonal)
    else:  # pragma: no cover - dolfinx >= 0.10
        A = mod.assemble_matrix(a, list(bcs), diagonal, kind="mpi")
    A.assemble()
    return A


def dofmap_list(V):
    """Cell -> dof (block) indices of V, as a 2-D (num_cells, dofs_per_cell) array.

    ``V.dofmap.list`` is that array on dolfinx >= 0.7 and an AdjacencyList in 0.5.
    """
    if NEW_API:  # pragma: no cover
        return V.dofmap.list
    return V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)   # also with 0 local cells


def num_entity_dofs(V, dim):
    """The dofs of V's element on one mesh entity of dimension ``dim`` (its interior, not its
    closure; per block).

    0.5-0.10: ``ElementDofLayout.num_entity_dofs(dim)``; 0.11 removed it (python/dolfinx/wrappers/
    fem.cpp at v0.11.0): the length of ``entity_dofs(dim, 0)``, the same for every entity of a
    dimension on a mesh of one cell type.
    """
    layout = V.dofmap.dof_layout
    if DOLFINX_VERSION >= (0, 11):  # pragma: no cover
        return len(layout.entity_dofs(dim, 0))
    return layout.num_entity_dofs(dim)


def solve_linear_problem(a, L, bcs, petsc_options, prefix):
    """Solve the linear variational problem a(u, w) = L(w) with Dirichlet ``bcs`` by
    ``dolfinx.fem.petsc.LinearProblem`` (its options under ``prefix``, e.g. "sdm_static_");
    returns the solution Function.

    0.10 and 0.11 require the keyword ``petsc_options_prefix`` (python/dolfinx/fem/petsc.py at
    v0.10.0, v0.11.0); 0.5-0.9 have no such argument (their prefix is chosen by dolfinx).
    """
    LinearProblem = petsc_module().LinearProblem
    if DOLFINX_VERSION >= (0, 10):  # pragma: no cover
        problem = LinearProblem(a, L, bcs=list(bcs), petsc_options=petsc_options, petsc_options_prefix=prefix)
    else:
        problem = LinearProblem(a, L, bcs=list(bcs), petsc_options=petsc_options)
    return problem.solve()


def trapezoid(y, x):
    """The trapezoidal rule: ``numpy.trapezoid`` (numpy >= 2; Debian 13) or ``numpy.trapz``."""
    return (np.trapezoid if hasattr(np, "trapezoid") else np.trapz)(y, x)


def interpolation_points(V):
    """Reference interpolation points of V's element (for ``fem.Expression``): a method in
    0.5, a property on newer versions."""
    points = V.element.interpolation_points
    return points() if callable(points) else points


class _XDMFFile:
    """dolfinx >= 0.7's XDMFFile, writing any Lagrange field as every version can.

    0.5 interpolates what it writes to the mesh vertices itself; newer versions accept only
    DG0 or Lagrange of the mesh's geometry degree (P2 on gmsh's curved meshes). A field of
    another degree is interpolated into that space (same mesh, same name) before writing.
    """

    def __init__(self, comm, path, mode):
        from dolfinx import io
        self._file = io.XDMFFile(comm, str(path), mode)
        self._out = {}

    def write_mesh(self, msh):
        self._file.write_mesh(msh)

    def write_function(self, u, t=0.0):
        V = u.function_space
        elem = V.ufl_element()
        degree = geometry_degree(V.mesh)
        if elem.embedded_superdegree == degree or (elem.embedded_superdegree == 0 and elem.discontinuous):
            self._file.write_function(u, t)
            return
        key = (u.name, u.ufl_shape)
        if key not in self._out:
            shape = u.ufl_shape
            Vout = fem.functionspace(V.mesh, ("Lagrange", degree, shape) if shape else ("Lagrange", degree))
            self._out[key] = fem.Function(Vout, name=u.name)
        out = self._out[key]
        out.interpolate(u)
        self._file.write_function(out, t)

    def close(self):
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __getattr__(self, name):    # read_mesh, write_meshtags, ...
        return getattr(self._file, name)


def xdmf_file(comm, path, mode="w"):
    """An XDMF file whose ``write_function`` takes P1 fields on any mesh (curved included)."""
    if NEW_API:  # pragma: no cover
        return _XDMFFile(comm, path, mode)
    from dolfinx import io
    return io.XDMFFile(comm, str(path), mode)


def package_version() -> str:
    """sdm_dolfinx's version as installed ("unknown" when run from a source tree without metadata)."""
    import importlib.metadata
    try:
        return importlib.metadata.version("sdm_dolfinx")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def file_sha256(path: Any) -> str:
    """The SHA-256 of a file's bytes (a problem file's identity in run.json and checkpoints)."""
    import hashlib
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def versions():
    """Library versions for run.json."""
    import basix
    import petsc4py
    return {"sdm_dolfinx": package_version(), "dolfinx": dolfinx.__version__, "basix": basix.__version__, "ufl": ufl.__version__,
            "petsc4py": petsc4py.__version__, "petsc": ".".join(map(str, PETSc.Sys.getVersion())),
            "mpi4py": __import__("mpi4py").__version__, "numpy": np.__version__,
            "mpi": MPI.Get_library_version().splitlines()[0].rstrip("\x00").strip()}


def interpolate_nonmatching(u_to, u_from, padding=1e-8):
    """Interpolate ``u_from`` into ``u_to``'s space with dolfinx's own non-matching mesh
    interpolation (same communicator, any partitions; points up to ``padding`` outside the
    source mesh are extrapolated from the nearest cell).

    Returns True when it interpolated, False when this dolfinx has none (0.5: the caller
    falls back to point evaluation, :func:`sdm_dolfinx.post.interpolate_nonmatching`).
    dolfinx 0.7-0.8: ``create_nonmatching_meshes_interpolation_data`` and
    ``interpolate(..., nmm_interpolation_data=)``; >= 0.9: ``create_interpolation_data``
    and ``Function.interpolate_nonmatching``.
    """
    if not NEW_API:
        return False
    V_to, V_from = u_to.function_space, u_from.function_space  # pragma: no cover - dolfinx >= 0.7
    tdim = V_to.mesh.topology.dim
    imap = V_to.mesh.topology.index_map(tdim)
    cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    if hasattr(fem, "create_interpolation_data"):
        data = fem.create_interpolation_data(V_to, V_from, cells, padding=padding)
        u_to.interpolate_nonmatching(u_from, cells, data)
    else:
        data = fem.create_nonmatching_meshes_interpolation_data(
            V_to.mesh._cpp_object, V_to.element, V_from.mesh._cpp_object, padding=padding)
        u_to.interpolate(u_from, nmm_interpolation_data=data)
    u_to.x.scatter_forward()
    return True


def dolfinx_version() -> str:
    """dolfinx's version string ("0.5.2", "0.11.0.post0", ...)."""
    return str(dolfinx.__version__)


def has_vtx() -> bool:
    """Whether this dolfinx writes VTX files (``dolfinx.io.VTXWriter``: built with ADIOS2). Debian 12's
    0.5.2 is not; PyPI's wheel dolfinx-solver-real (0.11) is."""
    from dolfinx import io
    return bool(getattr(dolfinx.common, "has_adios2", False)) and hasattr(io, "VTXWriter")


def vtx_writer(comm, path, functions):
    """dolfinx's VTXWriter of ``functions`` (a Function or a list of Functions of one space) at ``path``
    (a ``.bp`` folder): ``write(t)`` then ``close()``. The same positional call on 0.5-0.11 (0.8 added
    keyword options: the engine, whether the mesh is written again at every step)."""
    from dolfinx import io
    return io.VTXWriter(comm, str(path), functions)


def vtk_mesh(V):
    """(topology, cell types, points) of a Lagrange space for a VTK/pyvista grid (points =
    the dof coordinates, in dof order). ``create_vtk_mesh`` up to 0.6, ``vtk_mesh`` later."""
    from dolfinx import plot
    if hasattr(plot, "vtk_mesh"):  # pragma: no cover
        return plot.vtk_mesh(V)
    return plot.create_vtk_mesh(V)


def interpolation_matrix(V0, V1):
    """The assembled PETSc matrix (V1 x V0) of the interpolation from ``V0`` into ``V1`` on the same mesh
    (dolfinx's C++ ``interpolation_matrix``, the same call on 0.5.2 to 0.11)."""
    from dolfinx.cpp.fem.petsc import interpolation_matrix as _interpolation_matrix
    A = _interpolation_matrix(V0._cpp_object, V1._cpp_object)
    A.assemble()
    return A
