"""Matplotlib drawings: the fallback of :mod:`.render` when pyvista is missing, and the
disc's curved P2 mesh over its foundation (the paper's Fig. 13, the demos).

Imports nothing of the package and only the standard library at load time (numpy and
matplotlib inside the functions): the fallbacks take a :class:`~sdm_dolfinx.io.xdmf_reader.Series`.
"""


def p2_edge_lines(xy, samples=9):
    """Polylines of the curved edges of quadratic triangles, for a matplotlib LineCollection.

    ``xy``: (ncells, 6, 2) node coordinates in dolfinx's P2 order (vertices 0-2, then the
    midpoint of edge v1-v2, v0-v2, v0-v1); returns (3 ncells, samples, 2).
    """
    import numpy as np
    s = np.linspace(0.0, 1.0, samples)[:, None]
    lines = []
    for a, m, b in ((1, 3, 2), (0, 4, 2), (0, 5, 1)):
        pa, pm, pb = xy[:, a, None, :], xy[:, m, None, :], xy[:, b, None, :]
        lines.append((1 - s) * (1 - 2 * s) * pa + 4 * s * (1 - s) * pm + s * (2 * s - 1) * pb)
    return np.concatenate(lines)


def draw_foundation(ax, x0, x1):
    """The rigid foundation y <= 0 (hatched) between x0 and x1 (mm)."""
    ax.axhline(0.0, color="k", lw=1.5)
    ax.fill_between([x0, x1], [-2.0, -2.0], [0.0, 0.0], color="0.85", hatch="///", lw=0)


def draw_disc_mesh(ax, xy, contact, title):
    """The disc's curved P2 mesh, its contact vertices (``contact``: (n, 2)), the foundation
    and the lowest point A, on a matplotlib axes (the paper's Fig. 13)."""
    import numpy as np
    from matplotlib.collections import LineCollection
    ax.add_collection(LineCollection(p2_edge_lines(xy), colors="k", linewidths=0.6))
    ax.plot(contact[:, 0], contact[:, 1], "o", color="tab:red", ms=3.5, label=f"contact vertices ({len(contact)})")
    a = contact[np.argmin(contact[:, 1])]
    ax.annotate("A", a, xytext=(a[0] + 1.5, a[1] - 2.5), fontsize=12)
    draw_foundation(ax, -22, 22)
    ax.set_xlim(-22, 22)
    ax.set_ylim(-2, 52)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title)



# ------------------------------------------------------------------------ matplotlib fallback
def _mpl():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def mpl_draw(fig, series, t, scale, kind, clim=None):
    import matplotlib.tri as mtri
    import numpy as np
    tri = series.linear_triangles()
    u = series.field("displacement", t)
    fig.clear()
    if kind == "membrane":
        ax = fig.add_subplot(projection="3d")
        x, y = series.points[:, 0], series.points[:, 1]
        tr = mtri.Triangulation(x, y, tri)
        obstacle = float(series.parameters.get("obstacle", 0.0))
        xx, yy = np.meshgrid([x.min(), x.max()], [y.min(), y.max()])
        ax.plot_surface(xx, yy, np.full_like(xx, scale * obstacle), color="0.7", alpha=0.6)
        surf = ax.plot_trisurf(tr, scale * u, cmap="viridis", linewidth=0.2, edgecolor="0.3",
                               vmin=None if clim is None else clim[0], vmax=None if clim is None else clim[1] * scale)
        act = series.field("active", t) > 0.5
        ax.scatter(x[act], y[act], scale * u[act], color="red", s=12)
        ax.set_zlim(min(scale * obstacle, scale * u.min()) - 0.02, max(scale * u.max(), 0.1))
        ax.set_title(f"t = {series.times[series.index(t)]:.3f} (vertical scale x{scale:g}; red: in contact)")
        fig.colorbar(surf, ax=ax, shrink=0.6, label=f"{scale:g} x displacement")
    else:
        ax = fig.add_subplot()
        xy = series.points[:, :2] + scale * u[:, :2]
        vm = series.von_mises(u)
        pc = ax.tripcolor(xy[:, 0], xy[:, 1], tri, facecolors=vm, cmap="inferno",
                          vmin=0 if clim is None else clim[0], vmax=None if clim is None else clim[1])
        ax.axhline(0.0, color="k") if series.problem_name != "plane_bar" else ax.axvline(0.0, color="k")
        ax.set_aspect("equal")
        ax.set_title(f"t = {series.times[series.index(t)]:.4g}")
        fig.colorbar(pc, ax=ax, label="von Mises stress")
    return ax


def picture_mpl(series, png, t, scale, kind):
    plt = _mpl()
    fig = plt.figure(figsize=(8, 6))
    mpl_draw(fig, series, t, scale, kind)
    fig.savefig(png, dpi=100)
    plt.close(fig)


def animation_mpl(series, path, times, scale, kind, fps):
    from matplotlib.animation import FuncAnimation, PillowWriter
    plt = _mpl()
    fig = plt.figure(figsize=(6.4, 6.4))
    clim = None
    if kind != "membrane":
        clim = series.stress_range(times)
    anim = FuncAnimation(fig, lambda i: mpl_draw(fig, series, times[i], scale, kind, clim), frames=len(times))
    anim.save(str(path), writer=PillowWriter(fps=fps))
    plt.close(fig)

