"""The report's 3-D pictures: the membrane on the obstacle (paper Fig. 1) and the disc at
maximal compression. pyvista renders them off screen in a child process
(:mod:`sdm_dolfinx.study.pyvista_scene`); without pyvista, or when it fails, matplotlib
draws them. Each returns a report :class:`~sdm_dolfinx.study.entry.Entry` (no numbers). Rank 0
only: the stored states are read with the serial HDF5 reader."""
from mpi4py import MPI

import numpy as np
import ufl

from sdm_dolfinx import compat, post
from sdm_dolfinx import io as sdm_io
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.pictures import peak_state, pick_state, render_pyvista
from sdm_dolfinx.study.series import Series
from sdm_dolfinx.study.plotting import cells_p2, pyplot
from sdm_dolfinx.problems import disc


# ----------------------------------------------------------------------------- membrane
def picture_membrane(study, runs_dir, out):
    """The membrane on the obstacle during the first impact (paper Fig. 1), rank 0."""
    from dolfinx import fem
    folder = runs_dir / study.fig1.name
    s = Series(folder)
    info, problem, W, Vs = post.rebuild(folder, MPI.COMM_SELF)
    reader = sdm_io.StateReader(folder, W, Vs, MPI.COMM_SELF)
    row = pick_state(s, reader, "n_active", upto=0.45)
    u, _ = reader.read(row)
    P1 = compat.function_space(problem.mesh, compat.element("Lagrange", compat.cell_name(problem.mesh), 1))
    u1 = fem.Function(P1)
    u1.interpolate(u)
    topo, types, x = compat.vtk_mesh(P1)
    z = u1.x.array.copy()
    t = float(reader.t[row])
    contact = z <= 1e-6 * 0.02
    title = (f"membrane, P1+/P0, h = 1/{info['problem']['args']['N']}, t = {t:.3g}: {int(contact.sum())} vertices "
             f"on the obstacle")
    png = out / "fig01_membrane_3d.png"
    scale = 10.0
    ok, reason = render_pyvista("membrane", {"topology": topo, "types": types, "points": x, "u": z, "scale": scale,
                                             "contact": x[contact] * [1, 1, 0] + [0, 0, 2e-4],
                                             "title": title + f" (vertical scale x{scale:g})"}, png)
    if not ok:
        _membrane_mpl(png, topo, x, z, contact, title + "\n(matplotlib 3-D: " + reason + ")")
    n = int(contact.sum())
    return Entry("fig01", f"Ours: {n} vertices rest on the obstacle at t = {t:.3g} ({_how(ok, reason)}). ",
                 Verdict.of(n > 0), png=png.name)


def _how(ok, reason):
    """How a picture was rendered (and why not with pyvista)."""
    return f"rendered with {'pyvista' if ok else 'matplotlib'}" + ("" if ok or not reason else f"; {reason}")


def _membrane_mpl(png, topo, x, z, contact, title):
    """The membrane picture with matplotlib's 3-D axes (pyvista unavailable)."""
    plt = pyplot()
    tri = topo.reshape(-1, 4)[:, 1:]
    fig = plt.figure(figsize=(9, 6.5))
    ax = fig.add_subplot(projection="3d")
    gx, gy = np.meshgrid([0, 1], [0, 1])
    ax.plot_surface(gx, gy, np.zeros_like(gx, dtype=float), color="0.6", alpha=0.35)
    ax.plot_trisurf(x[:, 0], x[:, 1], z, triangles=tri, cmap="viridis", edgecolor="k", linewidth=0.2, alpha=0.95)
    ax.scatter(x[contact, 0], x[contact, 1], z[contact], color="tab:red", s=12, label="in contact")
    ax.set_zlim(0, 0.021)
    ax.set_box_aspect((1, 1, 0.35))
    ax.view_init(elev=22, azim=-60)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("u")
    ax.legend(loc="upper left")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    plt.close(fig)


# --------------------------------------------------------------------------------- disc
def von_mises_cells(u, lame_lambda, lame_mu):
    """Plane-strain von Mises stress of the displacement u, one value per owned cell (DG0:
    σ of Hooke's law (16) at the cell's interpolation point, σ_zz = λ tr ε)."""
    from dolfinx import fem
    msh = u.function_space.mesh
    Q0 = compat.function_space(msh, compat.element("DG", compat.cell_name(msh), 0))
    sig = disc.sigma(u, lame_lambda, lame_mu)
    szz = lame_lambda * ufl.tr(ufl.sym(ufl.grad(u)))
    vm_expr = ufl.sqrt(0.5 * ((sig[0, 0] - sig[1, 1]) ** 2 + (sig[1, 1] - szz) ** 2 + (szz - sig[0, 0]) ** 2)
                       + 3.0 * sig[0, 1] ** 2)
    vm = fem.Function(Q0)
    vm.interpolate(fem.Expression(vm_expr, compat.interpolation_points(Q0)))
    ncells = msh.topology.index_map(msh.topology.dim).size_local
    return vm.x.array[:ncells].copy()


def picture_disc(study, runs_dir, out):
    """The P2/P1 disc at maximal compression, as a plane-strain cylinder (rank 0)."""
    dt = min(study.disc["P2/P1"])
    folder = runs_dir / study.disc["P2/P1"][dt].name
    info, problem, W, u, t, force = peak_state(folder)
    args = info["problem"]["args"]
    vm = von_mises_cells(u, args["lame_lambda"], args["lame_mu"])
    title = (f"disc, P2/P1, level 1, dt = {dt:g} s: maximal compression at t = {1e3 * t:.2f} ms "
             f"(contact force {force:.0f} N/mm), von Mises stress")
    png = out / "disc_deformed_3d.png"
    depth = 15.0
    topo, types, x = compat.vtk_mesh(W)
    disp = np.zeros((len(x), 3))
    disp[:, :2] = u.x.array.reshape(-1, 2)[:len(x)]
    ok, reason = render_pyvista("disc", {"topology": topo, "types": types, "points": x, "disp": disp, "vm": vm,
                                         "depth": depth, "title": title}, png)
    if not ok:
        _disc_mpl(png, W, u, vm, depth, title + "\n(matplotlib 3-D, true scale: " + reason + ")")
    return Entry("disc3d", f"Ours: maximal compression at t = {1e3 * t:.2f} ms with a contact force of {force:.0f} N "
                 f"per mm ({_how(ok, reason)}). ", Verdict.of(force > 0), png=png.name)


def _disc_mpl(png, W, u, vm, depth, title):
    """The disc picture with matplotlib's 3-D axes (pyvista unavailable): front face coloured
    by von Mises, back face grey, on the foundation."""
    import matplotlib
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    plt = pyplot()
    cells = cells_p2(W)
    xy = W.tabulate_dof_coordinates()[:, :2][cells] + u.x.array.reshape(-1, 2)[cells]
    sub = np.array([[0, 5, 4], [5, 1, 3], [4, 3, 2], [5, 3, 4]])
    tris = xy[:, sub, :].reshape(-1, 3, 2)
    vals = np.repeat(vm, 4)
    norm = matplotlib.colors.Normalize(vals.min(), vals.max())
    cmap = matplotlib.colormaps["viridis"]
    fig = plt.figure(figsize=(10, 7))
    ax = fig.add_subplot(projection="3d")
    # coordinates (x, z = depth, y = height) so that "up" is the paper's y
    ax.add_collection3d(Poly3DCollection([[(-28, -4, 0), (28, -4, 0), (28, depth + 4, 0), (-28, depth + 4, 0)]],
                                         facecolor="0.75", alpha=0.5))
    back = [[(p[0], depth, p[1]) for p in tri] for tri in tris]
    ax.add_collection3d(Poly3DCollection(back, facecolor="0.55", edgecolor="none", alpha=0.6))
    front = [[(p[0], 0, p[1]) for p in tri] for tri in tris]
    ax.add_collection3d(Poly3DCollection(front, facecolors=cmap(norm(vals)), edgecolor="none"))
    ax.set_xlim(-25, 25)
    ax.set_ylim(-5, depth + 20)
    ax.set_zlim(-1, 45)
    ax.set_box_aspect((50, 40, 46))
    ax.view_init(elev=12, azim=-62)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_zlabel("y (mm)")
    sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.6, label="von Mises stress (N/mm$^2$), per cell")
    ax.set_title(title, fontsize=9)
    fig.savefig(png, dpi=90)
    plt.close(fig)
