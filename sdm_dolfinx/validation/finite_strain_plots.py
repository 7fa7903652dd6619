"""The figures of the report's section "Finite strain" from the rows of
:mod:`sdm_dolfinx.validation.finite_strain` (rank 0; each returns its file's name)."""
import numpy as np

from sdm_dolfinx.study.plotting import COLOURS, pyplot, save

#: the materials' colours, the same in every figure
COLOUR = {"linear": COLOURS[1], "neo-hookean": COLOURS[0], "svk": COLOURS[2]}


def plot_spin(rows, path):
    """The spinning square: its outline at half a turn, its area against 1 + (omega t)^2, and the
    hyperelastic runs' energy and angular-momentum drifts."""
    from sdm_dolfinx.validation.finite_strain import OMEGA
    plt = pyplot()
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.3))
    a.plot([0, 1, 1, 0, 0], [0, 0, 1, 1, 0], color="0.6", ls=":", label="t = 0")
    for r in rows:
        col = COLOUR.get(r["material"], "k")
        if r["outline"] is not None:
            o = np.asarray(r["outline"])
            a.plot(o[:, 0], o[:, 1], color=col, lw=1.5, label=r["material"])
        b.plot(r["area_t"], r["area"], color=col, lw=1.5, label=r["material"])
        if r["angular_drift"] is not None:
            t, E, L = (np.asarray(r[k]) for k in ("t", "energy", "angular_momentum"))
            c.semilogy(t[1:], np.maximum(np.abs(E[1:] - E[0]) / E[0], 1e-17), color=col, lw=1.2,
                       label=f"{r['material']}: |E - E0| / E0")
            c.semilogy(t[1:], np.maximum(np.abs(L[1:] - L[0]) / abs(L[0]), 1e-17), color=col, lw=1.0, ls=":",
                       label=f"{r['material']}: |L - L0| / |L0|")
    t = np.linspace(0.0, max(r["t"][-1] for r in rows), 200)
    b.plot(t, 1 + (OMEGA * t) ** 2, color="k", ls="--", lw=1, label="1 + (ω t)²")
    a.set_aspect("equal")
    return _finish(fig, (a, "outline at t = π / ω (half a turn of the initial ω)", None, None, "upper left"),
                   (b, "area of the spinning square (1 at rest)", "t", "area", None),
                   (c, "energy and angular momentum drift (hyperelastic)", "t", None, None), path=path)


def _finish(fig, *panels, path):
    """Title, labels, legend and grid of each panel ``(ax, title, xlabel, ylabel, legend location)``; save."""
    for ax, title, xlabel, ylabel, loc in panels:
        ax.set_title(title, fontsize=10)
        if xlabel:
            ax.set_xlabel(xlabel)
        if ylabel:
            ax.set_ylabel(ylabel)
        ax.legend(fontsize=8, **({"loc": loc} if loc else {}))
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return save(fig, path)


def plot_rolling(rows, path):
    """The rolling disc: the hyperelastic disc's outline at a few times (a material point marked), the
    centre's advance against R times the turned angle, and the energy."""
    plt = pyplot()
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.3), gridspec_kw={"width_ratios": [1.6, 1, 1]})
    R = 20.0
    for r in rows:
        col = COLOUR.get(r["material"], "k")
        if r["material"] != "linear":
            for k, o in sorted(r["outlines"].items(), key=lambda kv: int(kv[0])):
                o = np.asarray(o)
                a.plot(o[:, 0], o[:, 1], color=col, lw=1.0)
                a.plot(o[0, 0], o[0, 1], "o", color="k", ms=4)
        last = r["outlines"][max(r["outlines"], key=int)]
        if r["material"] == "linear":
            o = np.asarray(last)
            a.plot(o[:, 0], o[:, 1], color=col, lw=1.2, label="linear, at the end")
        b.plot(R * np.abs(r["theta"]), r["xc"], color=col, lw=1.5, label=r["material"])
        E = np.asarray(r["energy"])
        c.plot(1e3 * np.asarray(r["t"]), E / E[0] - 1, color=col, lw=1.2, label=f"{r['material']}: E / E0 - 1")
        c.plot(1e3 * np.asarray(r["t"]), (E + np.asarray(r["dissipated"])) / E[0] - 1, color=col, lw=1, ls=":",
               label=f"{r['material']}: (E + dissipated) / E0 - 1")
    a.axhline(0.0, color="0.3", lw=1)
    a.set_aspect("equal")
    top = max(R * np.abs(r["theta"][-1]) for r in rows)
    b.plot([0, top], [0, top], color="k", ls="--", lw=1, label="rolling without slip")
    return _finish(fig, (a, "one revolution: the neo-Hookean disc (• a material point), the linear one at the end",
                         None, None, "upper right"),
                   (b, "advance against rotation", "R |θ| (mm)", "centre's advance (mm)", None),
                   (c, "energy (friction's dissipation dotted)", "t (ms)", None, None), path=path)


def plot_ball(rows, path):
    """The ball against Hertz as the speed grows: the errors of t_c, F_max and delta_max, each material."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.0), sharex=True)
    for ax, (key, name) in zip(axes, (("err_t_c", "contact time t_c"), ("err_F_max", "peak force F_max"),
                                      ("err_delta_max", "largest approach δ_max"))):
        for material in dict.fromkeys(r["material"] for r in rows):
            mine = sorted((r for r in rows if r["material"] == material), key=lambda r: r["speed"])
            ax.semilogx([r["delta_over_R"] for r in mine], [100 * r[key] for r in mine], "o-",
                        color=COLOUR.get(material, "k"), label=material)
        ax.axhspan(-5, 5, color="0.9", zorder=0, label="±5 %")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlabel("Hertz's δ_max / R")
        ax.set_ylabel("error against Hertz (%)")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    levels = sorted({r["level"] for r in rows})
    speeds = sorted({r["speed"] for r in rows})
    fig.suptitle(f"the ball against Hertz as the speed grows: v = {', '.join(f'{v:g}' for v in speeds)} mm/s "
                 f"(level {', '.join(map(str, levels))}, P2/P1)", fontsize=10)
    fig.tight_layout()
    return save(fig, path)
