"""The mesh of the disc (paper section 5, Fig. 13): curved quadratic triangles made by gmsh.

The disc is built on one rank with gmsh's built-in kernel from four quarter arcs, so its
lowest point A is a mesh vertex; ``setOrder(2)`` puts the edge midpoints of boundary
triangles on the circle (P2 geometry). dolfinx then distributes it. No mesh file is
stored: the same gmsh version gives the same mesh. ``disc --mesh FILE.msh`` reads a mesh of
one's own instead (:func:`read_mesh`; :func:`write_msh` writes ours as a starting point), and
``disc --mesh FILE.mesh`` a GetFEM mesh (:mod:`.getfem_mesh`), such as the paper's own meshes.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.problems import getfem_mesh

#: facet tags of the boundary: the lower and the upper half circle
LOWER, UPPER = 1, 2

#: named mesh levels: level -> gmsh mesh size h (mm), chosen so that the P2 vector
#: displacement dof count is close to the paper's Table 2 (see :data:`LEVEL_DOFS`)
LEVELS = {1: 4.7, 2: 2.18, 3: 1.07, 4: 0.53, 5: 0.315, 6: 0.1575}
#: the P2 dof counts these sizes give with gmsh 4.8 (another gmsh version may differ a little)
LEVEL_DOFS = {1: 618, 2: 2786, 3: 11130, 4: 45458, 5: 126178, 6: 512568}
#: gmsh 2-D algorithm: 1 = MeshAdapt. Its dof counts match Table 2 within 2 % at every level;
#: Frontal-Delaunay (6, gmsh's default) jumps in larger steps on the coarse levels (692
#: or 540 dofs around level 1).
ALGORITHM = 1
#: the paper's dof counts (Table 2), for reference
PAPER_DOFS = {1: 622, 2: 2782, 3: 11306, 4: 45706, 5: 126892, 6: 511386}
#: the smallest mesh size, relative to the radius: h = radius / 1000 makes ~8 million triangles
#: (60 times level 6, h = radius / 127; ~30 million P2 dofs); below it gmsh is not even asked
#: (h = 1e-300 left it hanging)
MIN_H_RATIO = 1e-3
#: a boundary vertex of a mesh file must lie on the circle to this relative tolerance
CIRCLE_RTOL = 1e-6


class MeshError(SdmError, ValueError):
    """A mesh file that cannot be used (missing, unreadable, not the disc)."""


def _build_model(gmsh, h, radius, centre, order, algorithm):
    """The disc in gmsh's current model: four quarter arcs (A is a vertex), physical groups
    1 (the surface), :data:`LOWER` and :data:`UPPER` (the half circles), meshed."""
    gmsh.model.add("disc")
    cx, cy = centre
    geo = gmsh.model.geo
    c = geo.addPoint(cx, cy, 0.0, h)          # the arcs' centre (not a mesh node)
    # bottom (A), right, top, left: A is a vertex of the mesh
    pts = [geo.addPoint(cx + radius * np.cos(t), cy + radius * np.sin(t), 0.0, h)
           for t in (-np.pi / 2, 0.0, np.pi / 2, np.pi)]
    arcs = [geo.addCircleArc(pts[i], c, pts[(i + 1) % 4]) for i in range(4)]
    loop = geo.addCurveLoop(arcs)
    surf = geo.addPlaneSurface([loop])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surf], 1)
    # arcs 0 (A -> right) and 3 (left -> A) form the lower half circle
    gmsh.model.addPhysicalGroup(1, [arcs[0], arcs[3]], LOWER)
    gmsh.model.addPhysicalGroup(1, [arcs[1], arcs[2]], UPPER)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.option.setNumber("Mesh.Algorithm", algorithm)
    gmsh.option.setNumber("Mesh.SecondOrderLinear", 0)   # midpoints on the circle
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)


class _Gmsh:
    """gmsh initialised and finalised around a block; gmsh >= 4.9 lets us see a session
    the caller opened and leave it open (gmsh 4.8 cannot tell: do not call these functions
    inside your own gmsh session there)."""

    def __enter__(self):
        import gmsh
        self.gmsh = gmsh
        # gmsh < 4.9 has no isInitialized: then assume nobody else uses gmsh
        self.owner = not getattr(gmsh, "isInitialized", lambda: False)()
        if self.owner:
            gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        return gmsh

    def __exit__(self, *exc):
        if self.owner:
            self.gmsh.finalize()
        else:
            self.gmsh.model.remove()                   # leave the caller's gmsh as it was


def estimate_mesh(h, radius):
    """The mesh :func:`make_mesh` would make, counted without gmsh: about 8 (radius / h)^2
    triangles (gmsh 4.8, MeshAdapt: 7.9 at level 6), half as many vertices plus half the
    boundary's, and the edges by Euler's formula (for memory estimates of a run)."""
    ratio = min(radius / h, 1e100)             # h = 1e-300 must not overflow
    cells = 8.0 * ratio ** 2
    vertices = 0.5 * cells + np.pi * ratio
    return {"vertices": vertices, "edges": vertices + cells - 1, "cells": cells}


def estimate(values):
    """A disc run's mesh from its declared parameter ``values`` (``level``, ``h``,
    ``mesh_file``, ``radius``), for ``ProblemSpec.estimate``: :func:`estimate_mesh`, with
    two components of u; None for a mesh file (its size is unknown until read)."""
    if values.get("mesh_file") is not None:
        return None
    h = values["h"] if values.get("h") is not None else LEVELS[values["level"]]
    by = ("h",) if values.get("h") is not None else ("level",)
    return {**estimate_mesh(h, values["radius"]), "value_size": 2, "by": by}


def check_size(h, radius):
    """MeshError when ``h`` is below :data:`MIN_H_RATIO` x ``radius``."""
    if not h >= MIN_H_RATIO * radius:
        raise MeshError(f"mesh size h = {h:g} mm is below radius / {1 / MIN_H_RATIO:g} = {MIN_H_RATIO * radius:g} mm "
                        f"(about {estimate_mesh(h, radius)['cells']:.2g} triangles); give a larger h or a --level")


def make_mesh(h, radius=20.0, centre=(0.0, 30.0), comm=MPI.COMM_WORLD, rank=0, order=2, algorithm=ALGORITHM):
    """The disc of radius ``radius`` centred at ``centre`` with gmsh mesh size ``h``.

    Only ``rank`` runs gmsh; the mesh is then distributed over ``comm``; every rank of
    ``comm`` must call this function.

    Args:
        h: gmsh mesh size (mm), see :data:`LEVELS`.
        radius, centre: the disc (mm).
        comm, rank: the mesh's communicator and the rank that runs gmsh.
        order: geometry degree (2: curved boundary triangles).
        algorithm: gmsh's ``Mesh.Algorithm``.

    Returns:
        (mesh, facet_tags) with facets tagged :data:`LOWER` (y <= centre) and :data:`UPPER`.

    Raises:
        MeshError: ``h`` below :data:`MIN_H_RATIO` x ``radius`` (on every rank, before gmsh).
    """
    check_size(h, radius)
    if comm.rank == rank:
        with _Gmsh() as gmsh:
            _build_model(gmsh, h, radius, centre, order, algorithm)
            msh, _, ft = compat.model_to_mesh(gmsh.model, comm, rank, gdim=2)
    else:
        msh, _, ft = compat.model_to_mesh(None, comm, rank, gdim=2)
    return msh, ft


def write_msh(path, h, radius=20.0, centre=(0.0, 30.0), order=2, algorithm=ALGORITHM):
    """Write the disc :func:`make_mesh` builds to a gmsh ``.msh`` file (serial, no dolfinx):
    a starting point for a mesh of one's own, read back with ``disc --mesh``."""
    check_size(h, radius)
    with _Gmsh() as gmsh:
        _build_model(gmsh, h, radius, centre, order, algorithm)
        gmsh.write(str(path))


def _open_msh(gmsh, path):
    """Open ``path`` in gmsh; None if it holds 2-D triangles (linear or quadratic) in a
    physical group, else why not."""
    from pathlib import Path
    path = Path(path)
    if not path.is_file():
        return f"{path}: no such file"
    try:
        gmsh.open(str(path))
        types = set(gmsh.model.mesh.getElementTypes(2)) if gmsh.model.getDimension() >= 2 else set()
        groups = gmsh.model.getPhysicalGroups(2)
    except Exception as e:                      # gmsh raises a plain Exception
        return f"{path}: gmsh cannot read it ({str(e).strip() or type(e).__name__})"
    if not types or not types <= {2, 9}:        # 3-node and 6-node triangles
        return f"{path}: no 2-D triangle mesh in it (element types {sorted(types) or 'none'})"
    if not groups:
        return f"{path}: no physical surface group (dolfinx reads the cells of physical groups)"
    return None


def _read_getfem(path, radius, centre, comm, rank):
    """A GetFEM ``.mesh`` disc, moved from GetFEM's placement (lowest point A at the origin,
    centre (0, ``radius``): the paper's ``disc_P2_h*.mesh``) to ours: translated by
    (centre_x, centre_y - radius), i.e. up by the height of A above the foundation."""
    try:
        return getfem_mesh.read(path, (centre[0], centre[1] - radius), comm=comm, rank=rank)
    except getfem_mesh.GetfemFormatError as e:
        raise MeshError(str(e)) from None


def read_mesh(path, radius, centre, comm=MPI.COMM_WORLD, rank=0):
    """The disc's mesh from a gmsh file, or a GetFEM file if its name ends in ``.mesh``
    (:func:`_read_getfem`): (mesh, facet_tags), the boundary facets tagged
    :data:`LOWER` (all nodes at y <= centre) and :data:`UPPER` from their coordinates, so
    that any mesh of the disc works. Raises :class:`MeshError` (on every rank) when the
    file is missing or unreadable, when its bounding box is not the disc of ``radius``
    centred at ``centre`` (1 % of the radius), or when a vertex of its boundary is not on
    that circle (relative tolerance :data:`CIRCLE_RTOL`: a square or an ellipse with the
    disc's bounding box is not the disc)."""
    getfem = str(path).lower().endswith(".mesh")
    # gmsh opens the file on ``rank`` and dolfinx distributes the model, as for make_mesh
    # (dolfinx 0.5.2's own gmshio.read_from_msh fails: it returns an undefined name)
    if getfem:
        msh, err = _read_getfem(path, radius, centre, comm, rank), None
    elif comm.rank == rank:
        with _Gmsh() as gmsh:
            err = comm.bcast(_open_msh(gmsh, path), root=rank)
            if err is None:
                msh = compat.model_to_mesh(gmsh.model, comm, rank, gdim=2)[0]
    else:
        err = comm.bcast(None, root=rank)
        if err is None:
            msh = compat.model_to_mesh(None, comm, rank, gdim=2)[0]
    if err:
        raise MeshError(err)
    x = msh.geometry.x
    lo, hi = np.empty(2), np.empty(2)
    comm.Allreduce(np.ascontiguousarray(x[:, :2].min(axis=0, initial=np.inf)), lo, op=MPI.MIN)
    comm.Allreduce(np.ascontiguousarray(x[:, :2].max(axis=0, initial=-np.inf)), hi, op=MPI.MAX)
    want_lo, want_hi = np.subtract(centre, radius), np.add(centre, radius)
    if np.max(np.abs(np.concatenate([lo - want_lo, hi - want_hi]))) > 0.01 * radius:
        raise MeshError(f"{path}: the mesh spans x in [{lo[0]:.4g}, {hi[0]:.4g}], y in [{lo[1]:.4g}, "
                        f"{hi[1]:.4g}] mm, not the disc of radius {radius:g} centred at ({centre[0]:g}, "
                        f"{centre[1]:g}): set --radius and --height to match it"
                        + (" (a GetFEM .mesh is read as centred at (0, radius) and moved up by the height)"
                           if getfem else ""))
    from dolfinx import mesh as dmesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    _check_on_circle(msh, path, radius, centre, comm)
    tol = 1e-8 * radius
    lower = dmesh.locate_entities_boundary(msh, tdim - 1, lambda p: p[1] <= centre[1] + tol)
    every = dmesh.locate_entities_boundary(msh, tdim - 1, lambda p: np.full(p.shape[1], True))
    upper = np.setdiff1d(every, lower)
    facets = np.concatenate([lower, upper]).astype(np.int32)
    values = np.concatenate([np.full(len(lower), LOWER), np.full(len(upper), UPPER)]).astype(np.int32)
    order = np.argsort(facets)
    return msh, dmesh.meshtags(msh, tdim - 1, facets[order], values[order])


def _check_on_circle(msh, path, radius, centre, comm):
    """MeshError unless every vertex of the boundary is at distance ``radius`` from ``centre``
    (relative tolerance :data:`CIRCLE_RTOL`; the edge midpoints of a 6-node file may be straight)."""
    from dolfinx import mesh as dmesh
    verts = dmesh.locate_entities_boundary(msh, 0, lambda p: np.full(p.shape[1], True))
    p = dmesh.compute_midpoints(msh, 0, verts)[:, :2] if len(verts) else np.zeros((0, 2))
    err = np.abs(np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1]) - radius) / radius
    k = int(np.argmax(err)) if len(err) else -1
    worst = max(comm.allgather((float(err[k]), tuple(map(float, p[k]))) if k >= 0 else (-1.0, None)),
                key=lambda t: t[0])
    if worst[0] > CIRCLE_RTOL:
        (x, y), d = worst[1], np.hypot(worst[1][0] - centre[0], worst[1][1] - centre[1])
        raise MeshError(f"{path}: the boundary is not the circle of radius {radius:g} mm centred at ({centre[0]:g}, "
                        f"{centre[1]:g}): its vertex ({x:.6g}, {y:.6g}) is {d:.6g} mm from the centre (relative "
                        f"tolerance {CIRCLE_RTOL:g})")


def p2_dofs(msh):
    """Global number of P2 vector (2 components) displacement dofs on ``msh``."""
    V = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 2, (2,)))
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


if __name__ == "__main__":   # pragma: no cover - prints the dof counts of the levels
    import sys
    levels = [int(a) for a in sys.argv[1:]] or [1, 2, 3, 4]
    for lev in levels:
        m, _ = make_mesh(LEVELS[lev])
        n = p2_dofs(m)
        if MPI.COMM_WORLD.rank == 0:
            print(f"level {lev}: h = {LEVELS[lev]} mm, P2 dofs = {n} (paper {PAPER_DOFS[lev]})", flush=True)
