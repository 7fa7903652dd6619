"""A finished run's fields as VTX files (ADIOS2's BP format, read natively by ParaView), where this
dolfinx has ADIOS2: ``python -m sdm_dolfinx vtx DIR``.

``solution.xdmf`` holds the run's fields at the mesh's nodes (P2 through quadratic cells, P1+ through
its vertex values). VTX keeps a field in its own finite element space instead: dolfinx's
``VTXWriter`` writes arbitrary-degree (discontinuous) Lagrange functions at their dofs. From
``state.h5`` (the exact dof vectors of every stored step), :func:`export_vtx` writes

- ``DIR/vtx/displacement.bp``: U^n in W^h; a Lagrange W^h as it is, P1+ interpolated into the
  Lagrange space of its bubble's degree (P3 on triangles, P4 on tetrahedra, P2 on intervals), which
  contains it: the same field, exactly;
- ``DIR/vtx/velocity.bp``: the physical velocity, as ``solution.xdmf``'s ``velocity``: C^-1 B V̄ in
  H^h for the singular dynamic method (P0 per cell, P1), V of the (U, V) block system for the
  consistent C, V̄ itself for the standard method (H^h = W^h).

A Lagrange field of lower degree than a curved mesh's geometry (P1 on the disc's quadratic cells) is
interpolated into the geometry's degree, which VTX needs: exact too. Each file holds every stored
step with its time. dolfinx 0.5.2 as Debian 12 packages it has no ADIOS2: :func:`export_vtx` then
refuses in one line (:class:`VTXUnavailable`).
"""
from pathlib import Path

from mpi4py import MPI

from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.io import PostprocessError, read_info
from sdm_dolfinx.io.reader import StateReader
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.post.rebuild_run import rebuild_problem

#: the folder of the VTX files in a run folder, and the files
VTX_FOLDER, VTX_FILES = "vtx", ("displacement.bp", "velocity.bp")


class VTXUnavailable(PostprocessError):
    """This dolfinx was built without ADIOS2: no VTX output (one line)."""


def lagrange_copy(f, name, element):
    """(a Function of a Lagrange space holding ``f`` exactly, whether it is ``f`` itself): ``f`` when
    its space (``element``: a pair's ``(family, degree)``) is P0 or Lagrange of at least the mesh
    geometry's degree, else a new Function of the continuous Lagrange space of the smallest such
    degree containing it (P1+: its bubble's)."""
    msh = f.function_space.mesh
    cell = compat.cell_name(msh)
    family, degree = element
    gdeg = compat.geometry_degree(msh)
    if family == "P+":
        degree = compat.BUBBLE_DEGREE[cell]
    elif degree == 0 or degree >= gdeg:
        f.name = name
        return f, True
    space = compat.function_space(msh, compat.element("Lagrange", cell, max(degree, gdeg), f.ufl_shape))
    return fem.Function(space, name=name), False


def export_vtx(folder, comm=MPI.COMM_WORLD):
    """Write ``folder/vtx/displacement.bp`` and ``velocity.bp`` from ``folder``'s ``state.h5``
    (collective); returns (their paths, the number of steps written).

    Raises:
        VTXUnavailable: this dolfinx has no ADIOS2.
        PostprocessError: the run cannot be rebuilt or its ``state.h5`` read.
    """
    if not compat.has_vtx():
        raise VTXUnavailable(f"this dolfinx ({compat.dolfinx_version()}) was built without ADIOS2, which VTX output "
                             f"needs (PyPI's wheel dolfinx-solver-real has it); solution.xdmf holds the same fields")
    folder = Path(folder)
    info = read_info(folder, comm)
    problem = rebuild_problem(info, comm)
    constrain = (info.get("run_options") or {}).get("constrain") or "vertices"
    disc = Discretisation(problem, info["pair"], info.get("mass"), quadrature.of_run(info), constrain=constrain)
    block = info.get("mass") == "consistent"
    Vs = disc.H if block else disc.W
    reader = StateReader(folder, disc.W, Vs, comm)
    u, vbar = fem.Function(disc.W), fem.Function(Vs)
    # the velocity as solution.xdmf writes it: C^-1 B Vbar in H^h, V itself (block), Vbar (H^h = W^h)
    physical = disc.H is not None and not block
    velocity = fem.Function(disc.H) if physical else vbar
    h_vec = disc.B.createVecLeft() if physical else None
    pair = disc.pair
    u_out, u_same = lagrange_copy(u, "displacement", pair.w)
    v_out, v_same = lagrange_copy(velocity, "velocity", pair.h if pair.h is not None else pair.w)
    out = folder / VTX_FOLDER
    if comm.rank == 0:
        out.mkdir(exist_ok=True)
    comm.Barrier()
    paths = [out / name for name in VTX_FILES]
    writers = [compat.vtx_writer(comm, path, f) for path, f in zip(paths, (u_out, v_out))]
    try:
        for i in range(len(reader)):
            reader.read(i, u, vbar)
            if physical:
                h = disc.physical_velocity(compat.petsc_vec(vbar), h_vec)
                velocity.x.array[:len(h.array)] = h.array
                velocity.x.scatter_forward()
            for f, target, same in ((u, u_out, u_same), (velocity, v_out, v_same)):
                if not same:
                    target.interpolate(f)
                    target.x.scatter_forward()
            for w in writers:
                w.write(float(reader.t[i]))
    finally:
        for w in writers:
            w.close()
    return paths, len(reader)
