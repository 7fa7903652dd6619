"""Matplotlib drawings: the fallback of :mod:`.render` when pyvista is missing, and the
disc's curved P2 mesh over its foundation (the paper's Fig. 13, the demos).

Imports nothing of the package and only the standard library at load time (numpy and
matplotlib inside the functions): the fallbacks take a :class:`~sdm_dolfinx.io.xdmf_reader.Series`
and :mod:`.render`'s ``Look`` (colour, title, obstacle). A 3-D body is drawn as its boundary
surface's straight triangles (matplotlib has no hidden-surface removal: pyvista draws it better).
"""

#: the edges' colours of the bodies of a run with ``bodies`` (1, 2, ...; render_pv's)
BODY_COLOURS = ("#1f77b4", "#2ca02c", "#17becf", "#e377c2", "#bcbd22", "#7f7fff")


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


def _membrane(fig, series, t, scale, look, clim):
    import matplotlib.tri as mtri
    import numpy as np
    u = series.field("displacement", t)
    ax = fig.add_subplot(projection="3d")
    x, y = series.points[:, 0], series.points[:, 1]
    obstacle = look.obstacle
    if obstacle.get("flat") is not None:
        xx, yy = np.meshgrid([x.min(), x.max()], [y.min(), y.max()])
        ax.plot_surface(xx, yy, np.full_like(xx, scale * obstacle["flat"]), color="0.7", alpha=0.6)
    elif obstacle.get("points"):
        p = np.asarray(obstacle["points"])
        ax.plot_trisurf(mtri.Triangulation(p[:, 0], p[:, 1]), scale * p[:, 2], color="0.7", alpha=0.6)
    surf = ax.plot_trisurf(mtri.Triangulation(x, y, series.linear_triangles()), scale * u, cmap="viridis",
                           linewidth=0.2, edgecolor="0.3", vmin=scale * clim[0], vmax=scale * clim[1])
    act = (series.field("active", t) > 0.5) & series.vertex_mask()
    ax.scatter(x[act], y[act], scale * u[act], color="red", s=12)
    low = scale * min(u.min(), obstacle["flat"] if obstacle.get("flat") is not None else u.min())
    ax.set_zlim(low - 0.02, max(scale * u.max(), low + 0.1))
    ax.set_title(look.title(t, int(act.sum()), "red"), fontsize=8)
    bar = fig.colorbar(surf, ax=ax, shrink=0.6)
    bar.set_label(look.colour_title.replace("\n", " ") + f", drawn x{scale:g}")
    return ax


def _obstacle_2d(ax, obstacle, lo, hi):
    import numpy as np
    c = obstacle.get("component")
    if c is None or not obstacle.get("points"):
        return
    if obstacle["flat"] is not None:
        v, span = obstacle["flat"], float(np.max(hi - lo))
        if c == 0:
            ax.axvline(v, color="k", lw=1.5)
            ax.axvspan(v - 0.05 * span, v, color="0.85", hatch="///", lw=0)
        else:
            ax.axhline(v, color="k", lw=1.5)
            ax.axhspan(v - 0.05 * span, v, color="0.85", hatch="///", lw=0)
        return
    p = np.asarray(obstacle["points"])
    p = p[np.argsort(p[:, 1 - c])]
    ax.plot(p[:, 0], p[:, 1], color="0.5", lw=3)


def _solid(fig, series, t, scale, look, clim):
    import numpy as np
    u = series.field("displacement", t)
    xy = series.points[:, :2] + scale * u[:, :2]
    ax = fig.add_subplot()
    pc = ax.tripcolor(xy[:, 0], xy[:, 1], series.linear_triangles(), look.values(u), shading="gouraud",
                      cmap="inferno", vmin=clim[0], vmax=clim[1])
    bodies = series.node_bodies(t)
    if bodies is not None:                  # each body's edges in its colour, named in a legend
        from matplotlib.collections import LineCollection
        tag, names = bodies
        tri = series.linear_triangles()
        for k, name in enumerate(names, start=1):
            mine = tri[tag[tri[:, 0]] == k]
            ax.add_collection(LineCollection(xy[np.concatenate([mine[:, [0, 1]], mine[:, [1, 2]], mine[:, [2, 0]]])],
                                             colors=BODY_COLOURS[(k - 1) % len(BODY_COLOURS)], linewidths=0.5,
                                             label=f"edges: {name}"))
        ax.legend(loc="lower left", fontsize=7)
    act = (series.field("active", t) > 0.5) & series.vertex_mask()
    ax.plot(xy[act, 0], xy[act, 1], "o", color="c", ms=4)
    _obstacle_2d(ax, look.obstacle, xy.min(axis=0), xy.max(axis=0))
    found = look.obstacle_shape(t)
    if found is not None and len(found[1]):
        from matplotlib.collections import LineCollection
        points, cells = found
        ax.add_collection(LineCollection(points[cells][:, :, :2], colors="0.5", linewidths=3))
    ax.set_aspect("equal")
    ax.set_title(look.title(t, int(act.sum()), "cyan"), fontsize=8)
    fig.colorbar(pc, ax=ax, label=look.colour_title.replace("\n", " "))
    return ax


def _solid3d(fig, series, t, scale, look, clim):
    """The body's boundary surface (straight triangles) coloured by the mean of its nodes' values,
    the obstacle as a grey plane or surface (matplotlib draws no hidden surfaces: a fallback)."""
    import matplotlib.tri as mtri
    import numpy as np
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    u = series.field("displacement", t)
    x = series.points + scale * u
    tri = series.surface_triangles()
    norm = colors.Normalize(vmin=clim[0], vmax=clim[1])
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(Poly3DCollection(x[tri], facecolors=cm.inferno(norm(look.values(u)[tri].mean(axis=1))),
                                         edgecolors="0.4", linewidths=0.1))
    lo, hi = x.min(axis=0), x.max(axis=0)
    o, c = look.obstacle, look.obstacle.get("component")
    if c is not None and o.get("points"):
        axes = [k for k in range(3) if k != c]
        if o["flat"] is not None:
            mid, half = 0.5 * (lo + hi), 0.8 * (hi - lo)
            corners = np.zeros((4, 3))
            corners[:, c] = o["flat"]
            corners[:, axes[0]] = mid[axes[0]] + half[axes[0]] * np.array([-1, 1, 1, -1])
            corners[:, axes[1]] = mid[axes[1]] + half[axes[1]] * np.array([-1, -1, 1, 1])
            ax.add_collection3d(Poly3DCollection([corners], facecolors="0.6", alpha=0.4))
            lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
        else:
            p = np.asarray(o["points"])
            t_ = mtri.Triangulation(p[:, axes[0]], p[:, axes[1]]).triangles
            ax.add_collection3d(Poly3DCollection(p[t_], facecolors="0.6", alpha=0.4))
    found = look.obstacle_shape(t)
    if found is not None and len(found[1]):
        points, cells = found
        ax.add_collection3d(Poly3DCollection(points[cells], facecolors="0.6", alpha=0.4))
        lo, hi = np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * np.max(hi - lo)))
    act = (series.field("active", t) > 0.5) & series.vertex_mask()
    ax.scatter(*x[act].T, color="c", s=6)
    ax.set_title(look.title(t, int(act.sum()), "cyan"), fontsize=8)
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap="inferno"), ax=ax, shrink=0.6,
                 label=look.colour_title.replace("\n", " "))
    return ax


def mpl_draw(fig, series, t, scale, look, clim):
    """One frame on ``fig`` (cleared first)."""
    fig.clear()
    draw = {"membrane": _membrane, "solid": _solid, "solid3d": _solid3d}[look.kind]
    return draw(fig, series, t, scale, look, clim)


def picture_mpl(series, png, t, scale, look):
    plt = _mpl()
    fig = plt.figure(figsize=(8, 6))
    mpl_draw(fig, series, t, scale, look, look.range([t]))
    fig.savefig(png, dpi=100, format="png")
    plt.close(fig)


def animation_mpl(series, path, times, scale, look, fps):
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter
    plt = _mpl()
    fig = plt.figure(figsize=(6.4, 6.4))
    clim = look.range(times)
    anim = FuncAnimation(fig, lambda i: mpl_draw(fig, series, times[i], scale, look, clim), frames=len(times))
    anim.save(str(path), writer=FFMpegWriter(fps=fps) if str(path).lower().endswith(".mp4") else PillowWriter(fps=fps))
    plt.close(fig)
