"""The inf-sup measurement (:mod:`.infsup`) for people: a report per result, the ``--sweep``
table and the log-log plot of beta against h."""
from sdm_dolfinx.analysis.infsup import TOL


def _fmt_beta(b):
    return "inf" if b is None else f"{b:.6g}"


#: what the report says of where K^h acts, by ``constrain``
WHERE = {"vertices": "the constraint at the constrained vertices (eq. (13))",
         "nodes": "the constraint at every dof of W^h on the constrained boundary (constrain='nodes': "
                  "P2's mid-edge nodes too)",
         "weighted": "the weighted gap's rows: the gap averaged against each constrained vertex's hat function "
                     "over the contact facets (constrain='weighted')"}


def report(r):
    """A human-readable block for one result."""
    names = {"N": "N", "level": "level", "h": "mesh size parameter", "diagonal": "diagonal", "mesh_file": "mesh"}
    par = ", ".join(f"{names[k]} = {v}" for k, v in r["parameters"].items() if k in names and v is not None)
    where = f"{par}; " if par else ""          # a problem without these parameters (a user's)
    lines = [
        f"{r['problem']} ({where}largest cell diameter {r['h']:.4g}), pair {r['pair']}, {r['ranks']} rank(s)",
        f"  {WHERE[r.get('constrain', 'vertices')]}",
        f"  dim W^h = {r['dim_W']} (Dirichlet dofs removed: {r['n_dirichlet']}), dim H^h = {r['dim_H']}, "
        f"N_g = {r['N_g']}, dim Ker(B) = {r['dim_ker_B']}",
        f"  count condition dim H^h <= dim W^h - N_g: {r['dim_H']} <= {r['dim_W'] - r['N_g']}: "
        f"{'yes' if r['count_condition'] else 'NO'}; dim Ker(B) >= N_g: {'yes' if r['kernel_condition'] else 'NO'}",
        f"  B: rank {r['rank_B']} of {r['dim_H']} rows: {'surjective' if r['B_surjective'] else 'NOT surjective'} "
        f"(Remark 1: {'every V0 admissible' if r['B_surjective'] else 'V0 must lie in Im(C^-1 B), eq. (6)'})"
        f"; sigma_min/sigma_max = {r['sigma_ratio_B']:.3g}",
        f"  M = B^T C^-1 B: rank {r['rank_M']} of {r['dim_W']}, {'singular' if r['M_singular'] else 'invertible'}"
        f" [{r['rank_M_method']}]",
        f"  beta (condition (7), Euclidean norms of coefficient vectors) = {_fmt_beta(r['beta'])}",
        f"  method: {r['method']} ({r['seconds']:.2f} s)",
        f"  verdict: {r['verdict'].upper()} (tolerance beta > {r['tolerance']:.1e}): {r['reason']}",
        f"  the paper: {r['paper']}" + ("" if r.get("constrain", "vertices") == "vertices" else
                                        " (with the constraint at the vertices: the paper's K^h, eq. (13))"),
    ]
    return "\n".join(lines)


SWEEP_HEADER = (f"{'pair':8s} {'param':>6s} {'h':>9s} {'dim W':>7s} {'dim H':>7s} {'N_g':>6s} {'dim Ker B':>9s} "
                f"{'beta':>10s} {'method':>9s}  verdict")


def sweep_line(r):
    """One line of the ``--sweep`` table for a result row."""
    return (f"{r['pair']:8s} {str(r['sweep_value']):>6s} {r['h']:9.4g} {r['dim_W']:7d} {r['dim_H']:7d} {r['N_g']:6d} "
            f"{r['dim_ker_B']:9d} {_fmt_beta(r['beta']):>10s} {r['method_short']:>9s}  {r['verdict']}")


def plot_sweep(rows, path, title=""):
    """Log-log beta against h, one curve per pair; beta <= tol is drawn as crosses on the tolerance line
    (with the names of the pairs concerned)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    tol = r_tol(rows)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ill, ill_h = [], set()
    for k, name in enumerate(dict.fromkeys(r["pair"] for r in rows)):
        pts = sorted((r["h"], r["beta"]) for r in rows if r["pair"] == name and r["beta"] is not None)
        good = [(h, b) for h, b in pts if b > tol]
        if good:
            ax.loglog(*zip(*good), "o-", color=f"C{k}", label=name)
        if len(good) < len(pts):
            ill.append(name)
            ill_h.update(h for h, b in pts if b <= tol)
    if ill:      # pairs with beta <= tol all sit on the tolerance line: one marker for them all
        ax.loglog(sorted(ill_h), [tol] * len(ill_h), "kx", ms=9, mew=2,
                  label=r"$\beta \leq$ tol (ill-posed): " + ", ".join(ill))
    ax.axhline(tol, color="grey", ls="--", lw=0.8, label=f"tolerance {tol:.1e}")
    ax.set_xlabel("h (largest cell diameter)")
    ax.set_ylabel(r"$\beta$ of condition (7)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def r_tol(rows):
    """The verdict tolerance on beta used for ``rows`` (the default when there are none)."""
    return rows[0]["tolerance"] if rows else TOL
