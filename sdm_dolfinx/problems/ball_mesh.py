"""The mesh of the ball (the 3-D analogue of the disc): curved quadratic tetrahedra made by gmsh.

gmsh's OpenCASCADE sphere has its two poles as geometric vertices, so the lowest point A (the
south pole, where the ball first touches the plane z = 0) is a mesh vertex; ``setOrder(2)``
puts the edge midpoints of the boundary tetrahedra on the sphere (P2 geometry). A size field
refines the mesh toward A: cells of size ``h_contact`` within :data:`REFINE_RADIUS` times the
Hertz contact radius a of A, growing by :data:`GRADING` per unit distance up to ``h`` (the
size far from the contact). The mesh is built on one rank and distributed by dolfinx; no mesh
file is stored (the same gmsh version gives the same mesh).

The levels (:data:`LEVELS`) give ``h`` relative to the radius R and ``h_contact`` relative to a,
so that the contact zone is resolved by the same number of cells whatever the ball's material
and speed: level 1 puts 2 cells on a (fast tests), each level adds about 2 more.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.problems.disc_mesh import MeshError  # noqa: F401  (one class: the CLI reports it in one line)
from sdm_dolfinx.problems.disc_mesh import _Gmsh     # the same gmsh session handling as the disc

#: facet tags of the boundary: the lower hemisphere (every node at z <= the centre) and the rest
LOWER, UPPER = 1, 2

#: level -> (R / h, a / h_contact): the far size relative to the radius and the contact size
#: relative to the Hertz contact radius a (P2 dof counts at the defaults: :data:`LEVEL_DOFS`)
LEVELS = {1: (2.0, 2.0), 2: (3.0, 4.0), 3: (4.0, 6.0), 4: (5.0, 8.0), 5: (6.0, 12.0), 6: (9.0, 18.0)}
#: the P2 vector dof counts of the levels at the default ball (R = 20 mm, a = 1.63 mm), gmsh 4.8
LEVEL_DOFS = {1: 6594, 2: 21750, 3: 53976, 4: 107397, 5: 291501, 6: 890127}
#: cells of size h_contact within REFINE_RADIUS x a of A: the Hertz contact zone and a margin for
#: a numerical contact radius larger than a (the zone's edge is where the pressure's sqrt is steep)
REFINE_RADIUS = 1.5
#: the size grows linearly with the distance beyond the refined zone, by GRADING mm per mm: 0.5
#: keeps neighbouring cells within a factor ~1.5 and the coarse levels small (0.3 doubles level 1)
GRADING = 0.5
#: the smallest contact size relative to the radius (below, gmsh would make ~1e8 cells)
MIN_H_RATIO = 1e-3


def sizes(level, radius, a):
    """(h, h_contact) in mm of a named ``level`` for a ball of ``radius`` and Hertz contact radius ``a``."""
    far, contact = LEVELS[level]
    return radius / far, min(a / contact, radius / far)


def _build_model(gmsh, h, h_contact, a, radius, centre, order):
    """The ball in gmsh's current model, refined toward its south pole, meshed (volume group 1)."""
    gmsh.model.add("ball")
    cx, cy, cz = centre
    vol = gmsh.model.occ.addSphere(cx, cy, cz, radius)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [vol], 1)
    # the south pole: the geometric vertex of smallest z (OCC's sphere has both poles as vertices)
    pole = min((tag for _, tag in gmsh.model.getEntities(0)), key=lambda t: gmsh.model.getValue(0, t, [])[2])
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [pole])
    th = field.add("Threshold")
    field.setNumber(th, "InField", dist)
    field.setNumber(th, "SizeMin", h_contact)
    field.setNumber(th, "SizeMax", h)
    field.setNumber(th, "DistMin", REFINE_RADIUS * a)
    field.setNumber(th, "DistMax", REFINE_RADIUS * a + (h - h_contact) / GRADING)
    field.setAsBackgroundMesh(th)
    for name, value in (("Mesh.MeshSizeFromPoints", 0), ("Mesh.MeshSizeFromCurvature", 0),
                        ("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.SecondOrderLinear", 0),
                        ("General.NumThreads", 1)):
        gmsh.option.setNumber(name, value)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)


def check_sizes(h, h_contact, radius):
    """MeshError unless MIN_H_RATIO x radius <= h_contact <= h <= radius."""
    if not MIN_H_RATIO * radius <= h_contact <= h <= radius:
        raise MeshError(f"mesh sizes must satisfy radius / {1 / MIN_H_RATIO:g} <= h_contact <= h <= radius "
                        f"(got h_contact = {h_contact:g} mm, h = {h:g} mm, radius = {radius:g} mm)")


def estimate_mesh(h, h_contact, a, radius):
    """The mesh :func:`make_mesh` would make, counted without gmsh (for memory estimates): the
    cells are the integral of 5 / h(x)^3 over the ball, h(x) the size field (gmsh 4.8 makes
    about 5 h^-3 tetrahedra per unit volume: levels 1 to 5 within 20 %); a tetrahedral mesh has
    about cells / 5.5 vertices and 7/6 cells edges."""
    r = np.linspace(0.0, 2.0 * radius, 4001)
    size = np.clip(h_contact + GRADING * (r - REFINE_RADIUS * a), h_contact, h)
    # the area of the sphere of radius r around A inside the ball: 2 pi r^2 (1 - r / (2 R)) (a cap)
    area = 2.0 * np.pi * r ** 2 * (1.0 - r / (2.0 * radius))
    cells = float(compat.trapezoid(5.0 * area / size ** 3, r))
    return {"vertices": cells / 5.5, "edges": 7.0 * cells / 6.0, "cells": cells}


def make_mesh(h, h_contact, a, radius=20.0, centre=(0.0, 0.0, 20.01), comm=MPI.COMM_WORLD, rank=0, order=2):
    """The ball of ``radius`` centred at ``centre``, of size ``h``, refined to ``h_contact``
    within :data:`REFINE_RADIUS` ``a`` of its south pole.

    Only ``rank`` runs gmsh; every rank of ``comm`` must call this function.

    Returns:
        (mesh, facet_tags): boundary facets tagged :data:`LOWER` (every vertex at z <= centre)
        and :data:`UPPER`.

    Raises:
        MeshError: sizes out of :func:`check_sizes` (on every rank, before gmsh).
    """
    check_sizes(h, h_contact, radius)
    if comm.rank == rank:
        with _Gmsh() as gmsh:
            _build_model(gmsh, h, h_contact, a, radius, centre, order)
            msh = compat.model_to_mesh(gmsh.model, comm, rank, gdim=3)[0]
    else:
        msh = compat.model_to_mesh(None, comm, rank, gdim=3)[0]
    return msh, tag_hemispheres(msh, centre[2], 1e-8 * radius)


def tag_hemispheres(msh, cz, tol):
    """Boundary facets tagged :data:`LOWER` (all vertices at z <= cz + tol) or :data:`UPPER`."""
    from dolfinx import mesh as dmesh
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, fdim + 1)
    lower = dmesh.locate_entities_boundary(msh, fdim, lambda x: x[2] <= cz + tol)
    every = dmesh.locate_entities_boundary(msh, fdim, lambda x: np.full(x.shape[1], True))
    upper = np.setdiff1d(every, lower)
    facets = np.concatenate([lower, upper]).astype(np.int32)
    values = np.concatenate([np.full(len(lower), LOWER), np.full(len(upper), UPPER)]).astype(np.int32)
    order = np.argsort(facets)
    return dmesh.meshtags(msh, fdim, facets[order], values[order])


def p2_dofs(msh):
    """Global number of P2 vector (3 components) displacement dofs on ``msh``."""
    V = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 2, (3,)))
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


if __name__ == "__main__":   # pragma: no cover - prints the dof counts of the levels at the defaults
    import sys
    R, A = 20.0, 1.6279844460308592          # the default ball's Hertz contact radius (ball.hertz())
    for lev in [int(s) for s in sys.argv[1:]] or [1, 2, 3]:
        hf, hc = sizes(lev, R, A)
        m, _ = make_mesh(hf, hc, A, R)
        n, est = p2_dofs(m), estimate_mesh(hf, hc, A, R)
        if MPI.COMM_WORLD.rank == 0:
            print(f"level {lev}: h = {hf:.4g} mm, h_contact = {hc:.4g} mm, P2 dofs = {n}, cells = "
                  f"{m.topology.index_map(3).size_global} (estimated {est['cells']:.0f})", flush=True)
