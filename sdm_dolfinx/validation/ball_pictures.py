"""The report's picture of the ball at maximal compression: the stored state of largest
contact force, cut by the axis plane y = 0 and coloured by the von Mises stress; the whole ball and
a close-up of the contact zone with Hertz's contact radius a and the depth 0.48 a of his largest
von Mises stress (0.62 p0 at nu = 0.3). pyvista renders it in a child process
(:mod:`sdm_dolfinx.study.pyvista_scene`, kind ``ball``); without it, matplotlib draws the cut's cells.
Rank 0 only (the states are read with the serial HDF5 reader)."""
import numpy as np
import ufl

from sdm_dolfinx import compat
from sdm_dolfinx.study.pictures import peak_state, render_pyvista
from sdm_dolfinx.study.plotting import pyplot
from sdm_dolfinx.problems import ball

#: Hertz's largest von Mises stress (ratio to p0) and its depth (ratio to a) at nu = 0.3, on the axis
#: (Johnson, Contact Mechanics, section 4.2: tau_1 = 0.31 p0 at z = 0.48 a; sigma_vm = 2 tau_1 there)
HERTZ_VM_MAX, HERTZ_VM_DEPTH = 0.62, 0.48
PNG = "ball_deformed_3d.png"


def cell_stresses(u, lame_lambda, lame_mu):
    """(von Mises, sigma_zz) (N/mm^2) of u, one value per owned cell (DG0: Hooke's law at the cell's
    interpolation point), and the cells' deformed centroids (mm)."""
    from dolfinx import fem
    msh = u.function_space.mesh
    Q0 = compat.function_space(msh, compat.element("DG", compat.cell_name(msh), 0))
    sig = ball.sigma(u, lame_lambda, lame_mu)
    dev = sig - ufl.tr(sig) / 3.0 * ufl.Identity(3)
    out = []
    for expr in (ufl.sqrt(1.5 * ufl.inner(dev, dev)), sig[2, 2]):
        f = fem.Function(Q0)
        f.interpolate(fem.Expression(expr, compat.interpolation_points(Q0)))
        out.append(f.x.array.copy())
    n = msh.topology.index_map(msh.topology.dim).size_local
    V = u.function_space
    cells = compat.dofmap_list(V)[:n]
    xu = V.tabulate_dof_coordinates() + u.x.array.reshape(-1, 3)
    centroids = xu[cells[:, :4]].mean(axis=1)            # the first four nodes of a P2 tetrahedron: vertices
    return out[0][:n], out[1][:n], centroids


def axis_profile(vm, centroids, a, radius=0.3, width=0.1, depth=2.0):
    """The von Mises stress along the axis: the mean over the cells whose centroid is within ``radius`` a of
    the axis, in slices of ``width`` a down to ``depth`` a below the plane; (slice centres, means), empty
    slices left out. Its maximum is compared with Hertz's (0.62 p0 at 0.48 a): the per-cell maximum
    itself sits in the surface cells (the contact acts at the vertices only)."""
    near = np.hypot(centroids[:, 0], centroids[:, 1]) < radius * a
    edges = np.arange(0.0, depth + 0.5 * width, width) * a
    k = np.digitize(centroids[near, 2], edges) - 1
    ok = (k >= 0) & (k < len(edges) - 1)
    total = np.bincount(k[ok], vm[near][ok], len(edges) - 1)
    count = np.bincount(k[ok], minlength=len(edges) - 1)
    keep = count > 0
    return (edges[:-1] + 0.5 * width * a)[keep], total[keep] / count[keep]


def picture_ball(folder, out):
    """The picture of the run in ``folder`` (rank 0); returns its numbers and how it was drawn."""
    info, problem, W, u, t, force = peak_state(folder)
    args = info["problem"]["args"]
    prm = problem.parameters
    ref = prm["hertz"]
    vm, szz, centroids = cell_stresses(u, prm["lame_lambda"], prm["lame_mu"])
    k = int(np.argmax(vm))
    z_axis, vm_axis = axis_profile(vm, centroids, ref["a"])
    j = int(np.argmax(vm_axis))
    dt = float(info["run_options"]["dt"]) if "run_options" in info else float(info.get("dt"))
    level = args.get("level", prm.get("level"))
    title = (f"ball, P2/P1, level {level}, dt = {dt:g} s: maximal compression (t = {1e3 * t:.2f} ms,\n"
             f"contact force {force:.2f} N; Hertz: {ref['F_max']:.2f} N), cut by the plane y = 0, true scale")
    png = out / PNG
    topo, types, x = compat.vtk_mesh(W)
    disp = u.x.array.reshape(-1, 3)[:len(x)]
    scene = {"topology": topo, "types": types, "points": x, "disp": disp, "vm": vm, "title": title,
             "radius": prm["radius"], "a": ref["a"], "depth": HERTZ_VM_DEPTH * ref["a"],
             "vm_label": "von Mises stress (N/mm^2)"}
    ok, reason = render_pyvista("ball", scene, png)
    entry = {"png": png.name, "renderer": "pyvista" if ok else "matplotlib", "t": t, "contact_force": force,
             "level": level, "dt": dt, "vm_max": float(vm[k]), "vm_max_at": centroids[k].tolist(),
             "vm_depth": float(z_axis[j]), "vm_axis_max": float(vm_axis[j]),
             "axis_profile": {"depth": z_axis.tolist(), "vm": vm_axis.tolist()},
             "szz_min": float(szz.min()), "a": ref["a"], "p0": ref["p0"]}
    if not ok:
        _ball_mpl(png, centroids, vm, ref, title + "\n(matplotlib: " + reason + ")")
        entry["reason"] = reason
    return entry


def _ball_mpl(png, centroids, vm, ref, title):
    """Without pyvista: the cells near y = 0 at their centroids, coloured by von Mises, near the contact."""
    plt = pyplot()
    a = ref["a"]
    near = (np.abs(centroids[:, 1]) < 0.5 * a) & (np.abs(centroids[:, 0]) < 4 * a) & (centroids[:, 2] < 4 * a)
    fig, ax = plt.subplots(figsize=(8, 5))
    sc = ax.scatter(centroids[near, 0], centroids[near, 2], c=vm[near], s=30, cmap="viridis")
    ax.plot([-a, a], [0, 0], "r", lw=3, label="Hertz's contact radius a")
    ax.plot([0], [HERTZ_VM_DEPTH * a], "kx", ms=10, label="Hertz's largest von Mises stress (0.48 a)")
    ax.axhline(0.0, color="0.4")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.legend(fontsize=8)
    fig.colorbar(sc, ax=ax, label="von Mises stress (N/mm$^2$), per cell")
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    plt.close(fig)
