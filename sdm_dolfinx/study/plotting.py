"""Plot helpers shared by the figures: matplotlib off screen, the colours, the paper's
three-panel layout (energy, displacement and contact stress at the probe)."""
import numpy as np

from sdm_dolfinx import compat

COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save(fig, path):
    """Write ``fig`` to ``path`` (PNG, 90 dpi), close it; returns the file name."""
    fig.savefig(path, dpi=90)
    pyplot().close(fig)
    return path.name


def plot_three(series, labels, title, path, disc=False, shifts=(None, None, None), stress_from=0):
    """Energy, displacement at the probe, contact stress at the probe (the paper's layout)."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.0))
    tscale = 1e3 if disc else 1.0
    E = np.concatenate([s["energy"] for s in series])
    for k, (s, lab) in enumerate(zip(series, labels)):
        c = COLOURS[k % len(COLOURS)]
        lw = 1.8 if k == 0 else 1.1
        t = tscale * s.t
        axes[0].plot(t, s["energy"], color=c, lw=lw, label=lab + (" (blew up)" if s.failed else ""))
        du = (shifts[1] or 0) * k
        axes[1].plot(t, s["u_probe"] + du, color=c, lw=lw, label=lab + (f" (+{du:g})" if du else ""))
        if k >= stress_from:
            dl = (shifts[2] or 0) * (k - stress_from)
            axes[2].plot(t, s["lambda_probe"] + dl, color=c, lw=lw, label=lab + (f" (+{dl:g})" if dl else ""))
    if np.nanmax(E) > 5 * abs(E[0]) and np.all(E > 0):
        axes[0].set_yscale("log")
    peaks = [float(np.max(s["lambda_probe"])) for s in series[stress_from:]]
    if len(peaks) > 1 and max(peaks) > 20 * max(min(peaks), 1e-300):
        axes[2].set_yscale("symlog", linthresh=max(min(peaks), 1e-12))    # one curve's spikes dwarf the rest
    what = "A" if disc else "the centre (0.5, 0.5)"
    axes[0].set_title("energy $J^h$" + (" (N mm)" if disc else ""))
    axes[1].set_title(f"{'vertical ' if disc else ''}displacement at {what}" + (" (mm)" if disc else ""))
    axes[2].set_title(f"contact stress at {what}" + (" (N/mm$^2$)" if disc else ""))
    if not disc:
        axes[1].axhline(0.0, color="k", lw=0.6)
    for ax in axes:
        ax.set_xlabel("t (ms)" if disc else "t")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path)


def cells_p2(V):
    """Per owned cell, the dof (block) indices of the P2 space V (6 per triangle)."""
    msh = V.mesh
    n = msh.topology.index_map(msh.topology.dim).size_local
    return compat.dofmap_list(V)[:n]
