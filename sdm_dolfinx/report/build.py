"""The report: every figure from the runs' files, then ``index.html`` (each of our figures
next to what the paper's figure shows and a verdict computed from our numbers) and
``numbers.json`` (every number quoted). Every figure and study is a
:class:`~sdm_dolfinx.study.entry.Entry`; the summary reads each entry's ``verdict``, never its
sentence."""
import html

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.paper import disc_figures, membrane_figures as figures, numbers, pictures_3d as pictures, table2
from sdm_dolfinx.paper.design import BE_PAIRS, MEMBRANE_PAIRS
from sdm_dolfinx.report import comparison_entry as compare_report, hertz_entry as hertz_report
from sdm_dolfinx.report import two_balls_entry as two_balls_report
from sdm_dolfinx.report import finite_strain_entry as finite_strain_report
from sdm_dolfinx.report import rod_contact_entry as rod_report
from sdm_dolfinx.report import table2_entry as table2_report
from sdm_dolfinx.study.runs import duration, read_run_info
from sdm_dolfinx.study.entry import Verdict
from sdm_dolfinx.study.text import html_table, jsonable
from sdm_dolfinx.validation import friction_impact, friction_rigid as friction

COMM = MPI.COMM_WORLD

#: what each of the paper's figures shows (from its text), the left half of each report entry
PAPER_SAYS = {
    "fig01": "Paper Fig. 1: the membrane (structured mesh, h = 0.05) during its first impact on the obstacle.",
    "fig02": "Paper Fig. 2 (P1+/P0, midpoint, h = 0.1): the energy tends to be conserved as dt decreases "
             "(dt = 1e-4 is not visibly different from 1e-3); the centre displacement and contact stress are "
             "smooth and converge as dt decreases.",
    "fig03": "Paper Fig. 3 (P1/P0, midpoint, h = 0.1): unstable. The energy grows very fast after the first "
             "impact, displacement and contact stress oscillate and do not converge, and the instabilities "
             "are more important for the smallest time step (the pair violates condition (7)).",
    "fig04": "Paper Fig. 4 (P1/P1, the standard Galerkin method, midpoint, h = 0.1): unstable like P1/P0; "
             "the energy grows very fast after the first impact, more so for the smaller time step.",
    "fig05": "Paper Fig. 5 (P1+/P1, midpoint, h = 0.1): stable and converging although condition (7) is "
             "not proved; dt = 1e-4 shows no visible difference with dt = 1e-3.",
    "fig06": "Paper Fig. 6 (P2/P1, midpoint, h = 0.1): stable and converging although condition (7) is not "
             "proved; dt = 1e-4 shows no visible difference with dt = 1e-3.",
    "fig07": "Paper Fig. 7 (P1+/P0, backward Euler, h = 0.1): smooth displacement and stress; the energy "
             "decreases, fast for large dt, and tends to be conserved as dt decreases (well-posed pair).",
    "fig08": "Paper Fig. 8 (P1/P0, backward Euler, h = 0.1): smooth results, but an energy loss at the "
             "impact that does not vanish as dt decreases (ill-posed pair).",
    "fig09": "Paper Fig. 9 (P1/P0, backward Euler, dt = 1e-3, several h): the energy lost at the impact does "
             "not vanish as the mesh is refined.",
    "fig10": "Paper Fig. 10 (midpoint, h and dt decreasing with dt/h fixed; curves shifted vertically): the "
             "centre displacement converges, slowly (impacts limit the smoothness); on the finest mesh "
             "(dt = 3.125e-4, h = 1/16) P1+/P0 and P2/P1 give similar results.",
    "fig11": "Paper Fig. 11 (midpoint, P1+/P0 and P2/P1): the relative energy error at the final time "
             "against dt/h, one curve per mesh size: for a fixed mesh the energy tends to be conserved as dt "
             "decreases, and at constant dt/h the error does not grow as the mesh is refined.",
    "fig13": "Paper Fig. 13: the disc's mesh with quadratic (curved) elements, h about 2 mm (622 dofs).",
    "fig14": "Paper Fig. 14 (standard P2 discretisation, midpoint, contact at every boundary node): close to "
             "energy conserving for dt = 1e-4 s but completely unstable for dt = 1e-5 s (the energy blows up "
             "at the beginning of the impact); the contact stress at A already oscillates at dt = 1e-4 s.",
    "fig15": "Paper Fig. 15 (P2/P1, midpoint, contact at the vertices): perfectly stable; the energy "
             "converges to a conserved one as dt decreases, and the contact stress at A seems to converge.",
    "fig16": "Paper Fig. 16 (P2/P1, h and dt decreasing together): the energy converges toward "
             "conservation, the stress at A converges fairly well, and the relative H1 error at t = 0.02 s "
             "against the finest mesh decreases at the rate 0.69.",
    "table2": "Paper Table 2: dt, h, number of dofs and relative H1 error at the final time (\"t = 0.02 s\") "
              "against the finest mesh (h = 0.07 mm, 511386 dofs): 5.86, 4.41, 2.57, 1.42, 0.43 %; rate 0.69 "
              "(fitted on rows 1-4).",
    "disc3d": "The deformed disc at maximal compression (no such picture in the paper; Fig. 12 sketches the "
              "setting).",
}

#: the friction section's heading (its entries say what their closed forms say)
_FRICTION_HEAD = ("<h2>Friction (not in the paper)</h2><p>Runs with Coulomb or Tresca friction at the "
                  "contact vertices (run options <code>--friction</code>, <code>--mu</code>, "
                  "<code>--tresca-threshold</code>), each next to the rigid-body closed form it should follow and a "
                  "sentence computed from our numbers.</p>")

_CSS = ("body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em;line-height:1.4}"
        "img{max-width:100%;border:1px solid #ccc}table{border-collapse:collapse;margin:0.5em 0}"
        "td,th{border:1px solid #bbb;padding:2px 6px;font-size:90%}.paper{color:#333}.ours{color:#024}"
        ".v-yes{background:#e6f5e6}.v-part{background:#fff5d6}.v-no{background:#fbe3e3}"
        "section{margin-bottom:2em;padding:0.6em;border-radius:6px}")


def make_report(study, runs_dir, out, records, comm=COMM, say=print, meta=None):
    """Every figure, the pictures and the report from the runs' files (collective); ``study`` a
    :class:`~sdm_dolfinx.report.studies.ReportStudy`."""
    entries = []
    paper = study.paper
    t2_errors = table2.table2_study(paper, runs_dir, comm, say)
    conv = table2.convergence(paper, t2_errors)
    checks = numbers.energy_checks(paper, runs_dir, comm)
    comparison = compare_report.entry(study, runs_dir, out, comm, say)     # collective runs
    rod = rod_report.entry(study, runs_dir, out, comm, say)                # collective runs
    ball = hertz_report.entries(study, runs_dir, out, comm, say)           # collective runs
    balls = two_balls_report.entry(study, runs_dir, out, comm, say)        # collective runs
    hyperelastic = finite_strain_report.entries(study, runs_dir, out, comm, say)     # collective runs
    if comm.rank == 0:
        entries.append(pictures.picture_membrane(paper, runs_dir, out))
        for pair in MEMBRANE_PAIRS:
            entries.append(figures.fig_pair(paper, pair, runs_dir, out))
        for pair in BE_PAIRS:
            entries.append(figures.fig_pair(paper, pair, runs_dir, out, "backward-euler"))
        entries += [figures.fig09(paper, runs_dir, out), figures.fig10(paper, runs_dir, out),
                    figures.fig11(paper, runs_dir, out), disc_figures.fig13(paper, runs_dir, out),
                    disc_figures.fig_disc(paper, "P2/P2", runs_dir, out),
                    disc_figures.fig_disc(paper, "P2/P1", runs_dir, out),
                    disc_figures.fig16(paper, conv, runs_dir, out)]
        t2 = table2_report.entry(paper, t2_errors, runs_dir)
        entries.append(t2)
        entries.append(pictures.picture_disc(paper, runs_dir, out))
        # not in the paper: closed forms instead
        entries += [friction.fig_incline(study.friction, runs_dir, out),
                    friction.fig_block(study.friction, runs_dir, out),
                    *friction_impact.impact_entries(study.friction, runs_dir, out)]
        if comparison is not None:
            entries.append(comparison)
        entries.append(rod)
        entries += ball
        entries.append(balls)
        entries += hyperelastic
        meta = dict(meta or {}, runs_dir=runs_dir)
        meta["runs_total"] = sum((read_run_info(runs_dir / r.name) or {}).get("wall_time") or 0.0
                                 for r in study.runs())
        write_report(out, entries, t2, checks, records, study, meta)
    comm.Barrier()
    return entries


#: the CSS class of an entry's section, by verdict
_VERDICT_CLASS = {Verdict.AGREES: "v-yes", Verdict.IN_PART: "v-part", Verdict.DISAGREES: "v-no"}


def summary(entries):
    """(key, verdict string) of every entry, in order: the report's summary table and numbers.json's
    ``verdicts`` (read from each entry's verdict, never from its sentence)."""
    return [(e.key, e.verdict.value) for e in entries]


def write_report(out, entries, t2, checks, records, study, meta):
    """index.html (figures next to the paper's statement and our computed verdict) + numbers.json;
    ``entries`` and ``t2`` (Table 2's) are :class:`~sdm_dolfinx.study.entry.Entry`."""
    verdicts = summary(entries)
    parts = _head(study, meta) + ["<h2>Summary</h2>" + html_table(["figure", "verdict"], verdicts)]
    first_friction = next((i for i, e in enumerate(entries) if e.says and not e.head and not e.section), None)
    for i, e in enumerate(entries):
        if i == first_friction:            # entries with a closed form of their own ("says"), not the paper's
            parts.append(_FRICTION_HEAD)
        if e.head:                         # a section of its own (the comparison of methods)
            parts.append(e.head)
        parts.append(_section(e))
    parts += _energy_section(checks) + _runs_section(study, records, meta) + ["</body></html>"]
    atomic_write_text(out / "index.html", "\n".join(parts))
    numbers = {"mode": "quick" if study.quick else "full", "meta": {k: str(v) for k, v in meta.items()},
               "figures": {e.key: jsonable(e.numbers) for e in entries},
               "verdicts": dict(verdicts), "energy_checks": checks, "table2": t2.numbers}
    atomic_write_text(out / "numbers.json", json_text(numbers, indent=1))


def _head(study, meta):
    """The page's head and its opening paragraphs (the paper, the mode, the settings)."""
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>sdm_dolfinx: Renard (2010) reproduced"
             f"</title><style>{_CSS}</style></head><body>",
             "<h1>The singular dynamic method, reproduced</h1>",
             "<p>Y. Renard, <i>The singular dynamic method for constrained second order hyperbolic equations: "
             "application to dynamic contact problems</i>, J. Comput. Appl. Math. 234 (2010) 906–923. Every figure "
             "below was regenerated from the output files of the runs listed at the end; each comes with what the "
             "paper's figure shows and a sentence, computed from our numbers, saying whether ours agrees.</p>",
             f"<p><b>Mode:</b> {'quick (coarser and shorter than the paper: a smoke test)' if study.quick else 'full'}"
             f"; {meta['ranks']} MPI rank(s); this invocation ran for {duration(meta['wall'])} ({meta['computed']} "
             f"runs computed, {meta['cached']} reused); the runs took {duration(meta['runs_total'])} in all (their "
             f"run.json wall times); command <code>{html.escape(meta['command'])}</code>; "
             f"{html.escape(meta['versions'])}.</p>"]
    parts.append("<p><b>Settings as in the paper's program:</b> the membrane on dolfinx's <code>left_right</code> "
                 "triangulation (GetFEM's 'regular simplices'), pairs with a P1 velocity (P1+/P1, P2/P1) with the "
                 "consistent C through the (U, V) system (4), P0 velocities with their exact diagonal C; contact at "
                 "the mesh vertices (13); the disc's P2/P2 run, unlike the paper's, constrains vertices only.</p>")
    if study.quick:
        parts.append("<p><b>Quick mode:</b> the membrane runs stop at T = 0.5 (the paper: 0.8), dt = 1e-4 is "
                     "skipped, Figs. 9-11 use fewer and coarser meshes, and the disc convergence study stops at "
                     "level 3, the friction runs use disc level 1 only, the ball and the two balls against Hertz level 1 only, "
                     "the finite-strain section one revolution of the spin, one time step of the rolling disc and "
                     "two speeds of the ball at level 1; verdicts refer to these runs.</p>")
    return parts


def _section(e):
    """One figure: the reference's statement, our sentence with the verdict's, the picture, its HTML
    (Table 2's rows)."""
    parts = [f"<section class='{_VERDICT_CLASS[e.verdict]}' id='{e.key}'><h2>{e.key}</h2>"
             f"<p class='paper'>{html.escape(e.says or PAPER_SAYS[e.key])}</p>"
             f"<p class='ours'>{html.escape(e.ours)}</p>"]
    if e.png:
        parts.append(f"<img src='{e.png}' alt='{e.key}'>")
    if e.html:
        parts.append(e.html)
    parts.append("</section>")
    return "\n".join(parts)


def _energy_section(checks):
    """The energy recomputed from state.h5 against the in-run energy."""
    return ["<h2>Energy recomputed from the stored fields</h2><p><code>python -m sdm_dolfinx energy DIR"
            "</code> reassembles J<sup>h</sup> from <code>state.h5</code> with the run's forms, independently "
            "of the in-run diagnostics; largest difference to <code>timeseries.csv</code> relative to max|J| "
            "and in units of eps times the round-off scale ½|U|ᵀ|A||U| + |U|ᵀ|L| + ½|V|ᵀ|M||V| (eps of the "
            "stored precision; O(1)-O(100) means agreement to round-off):</p>",
            html_table(["run", "stored states", "max relative difference", "in eps of round-off scale",
                         "state.h5 dtype"],
                        [(c["run"], c["states"], f"{c['max_rel_diff']:.2e}",
                          f"{c['max_roundoff_ratio'] / np.finfo(np.dtype(c['stored_dtype'])).eps:.3g}",
                          c["stored_dtype"]) for c in checks])]


def _runs_section(study, records, meta):
    """Every run: its command line, status, size and run time."""
    rows = []
    for r in study.runs():
        rec = records.get(r.name, {})
        info = read_run_info(meta["runs_dir"] / r.name) or {}
        status = info.get("status", "?") + (f": {info.get('error', '')}" if info.get("status") == "failed" else "")
        rows.append((r.name, r.command_line(), info.get("linear", ""), status, info.get("dim_W", ""),
                     info.get("steps", ""), "" if info.get("wall_time") is None else f"{info['wall_time']:.1f} s",
                     "reused" if rec.get("cached") else "computed"))
    return ["<h2>Runs</h2><p>Each is <code>python -m sdm_dolfinx</code> with the options shown and "
            f"<code>--out {html.escape(str(meta['runs_dir']))}/NAME</code>.</p>",
            html_table(["name", "options", "linear solves", "status", "dim W", "steps", "run time",
                         "this study"], rows)]
