"""The report's section "3-D: two balls against Hertz" (not in the paper): the two-ball study of
:mod:`sdm_dolfinx.validation.two_balls` (head on and unequal) at the report's levels, resumable, with its
table, the force histories against Hertz's and a verdict on the issue's criterion: t_c and F_max within 5 %
of Hertz on the finest level, for both cases.

The rows are kept in ``runs_dir/two_balls/two_balls.json`` with what defines them (the runs, the cases, the
package's version); a rerun with the same definition reads them.
"""
import html
import json
import time
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.text import html_table
from sdm_dolfinx.validation import two_balls as tb

ROWS_FILE = "two_balls.json"
#: the mesh levels of the report's runs, cheapest first (each case at its own dt: validation.two_balls.CASES)
LEVELS = {True: (1,), False: (1, 2)}
#: the issue's criterion on the finest level
TOLERANCE = 0.05
SAYS = ("Hertz (1882) for two elastic spheres, quasi-statically: the curvatures add (1/R* = 1/R1 + 1/R2), the "
        "compliances add (1/E* = (1 − ν1²)/E1 + (1 − ν2²)/E2) and the masses combine into the reduced mass m*; the "
        "approach speed is v1 + v2, and the one-sphere formulas give F_max and t_c. Two equal balls (R = 20 mm, "
        "E = 10 N/mm², ν = 0.3, ρ = 1000 kg/m³) at ±100 mm/s: F_max = 3.161 N, t_c = 3.896 ms, each ball as the "
        "single ball on a rigid plane. Ball 2 with R2 = 10 mm, E2 = 40 N/mm², ρ2 = 3000 kg/m³ at rest, struck at "
        "100 mm/s: F_max = 1.064 N, t_c = 3.16 ms. The impulse is 2 m* (v1 + v2) (an elastic rebound of the relative "
        "motion), and the total momentum is constant. The issue's criterion: t_c and F_max within 5 % of Hertz on "
        "the finest level.")
HEAD = ("<h2>3-D: two balls against Hertz (not in the paper)</h2><p>Contact between two deformable bodies "
        "(<code>python -m sdm_dolfinx two_balls</code>: one mesh of two balls, the lower hemisphere of ball 1 held "
        "outside the upper hemisphere of ball 2 by node-to-surface rows, P2/P1, the midpoint scheme): the singular "
        "mass on both bodies, the contact force between them against Hertz's for two spheres. Same runs as "
        "<code>python demos/two_balls.py</code>; docs/contact.md describes the method and its other checks.</p>")


def key(quick):
    """What defines the study's rows (stored rows with another definition are recomputed)."""
    return {"levels": list(LEVELS[bool(quick)]), "cases": {k: [v, dt] for k, (v, dt) in tb.CASES.items()},
            "after": tb.AFTER, "version": compat.package_version()}


def read_rows(folder, quick):
    """The stored rows of ``folder`` when their definition is :func:`key`'s, else None (not collective)."""
    try:
        stored = json.loads((Path(folder) / ROWS_FILE).read_text())
    except (OSError, ValueError):
        return None
    want = json.loads(json_text(key(quick)))
    return stored.get("rows") if isinstance(stored, dict) and stored.get("key") == want else None


def run_study(folder, quick, comm=MPI.COMM_WORLD, say=print):
    """The rows, read when stored, computed otherwise (collective); (rows, computed: bool)."""
    rows = comm.bcast(read_rows(folder, quick) if comm.rank == 0 else None, root=0)
    if rows is not None:
        return rows, False
    levels = LEVELS[bool(quick)]
    say(f"two balls against Hertz: {len(levels) * len(tb.CASES)} runs in {folder}")
    rows = []
    for level in levels:
        for case in tb.CASES:
            t0 = time.perf_counter()
            rows.append(tb.run_one(case, level, comm=comm))
            say(f"  two balls, {case}, level {level}: {time.perf_counter() - t0:.0f} s")
    if comm.rank == 0:
        Path(folder).mkdir(parents=True, exist_ok=True)
        atomic_write_text(Path(folder) / ROWS_FILE, json_text({"key": key(quick), "rows": rows}))
    comm.Barrier()
    return rows, True


def entry(study, runs_dir, out, comm=MPI.COMM_WORLD, say=print):
    """Run (unless stored) and draw the section (collective); its entry on rank 0, None elsewhere."""
    t0 = time.perf_counter()
    rows, computed = run_study(Path(runs_dir) / "two_balls", study.quick, comm, say)
    if comm.rank != 0:
        return None
    folder = Path(out) / "two_balls"
    folder.mkdir(parents=True, exist_ok=True)
    tb.plot(rows, folder / "two_balls_hertz.png")
    return make_entry(rows, computed, time.perf_counter() - t0)


def ours(rows):
    """(sentence, verdict): agrees when t_c and F_max are within :data:`TOLERANCE` of Hertz for both cases on
    the finest level, in part when some are."""
    finest = max(r["level"] for r in rows)
    top = [r for r in rows if r["level"] == finest]
    ok = [abs(r[e]) <= TOLERANCE for r in top for e in ("err_t_c", "err_F_max")]
    each = "; ".join(f"{r['case']}, level {r['level']}: t_c {100 * r['err_t_c']:+.1f} %, F_max "
                     f"{100 * r['err_F_max']:+.1f} %, impulse {100 * r['err_impulse']:+.2f} %" for r in rows)
    text = (f"Ours (P2/P1, midpoint, node-to-surface rows between the balls; errors against Hertz): {each}. The total "
            f"momentum stays constant to {max(r['momentum_drift'] for r in rows):.0e} of ball 1's (the contact forces "
            f"are equal and opposite), the energy within {100 * max(r['energy_drift'] for r in rows):.2f} %. "
            f"On the finest level (level {finest}) {sum(ok)} of {len(ok)} numbers are within "
            f"{100 * TOLERANCE:.0f} % of Hertz. ")
    return text, Verdict.of(all(ok), any(ok))


def make_entry(rows, computed, seconds):
    """The section's entry: the table, the figure, the sentence and the numbers."""
    text, verdict = ours(rows)
    body = html_table(tb.HEADER, tb.table_rows(rows)) + (
        f"<p>{'Computed' if computed else 'Read'} in {seconds:.0f} s (files in <code>two_balls/</code>). "
        + html.escape("t_c counts the steps with a contact force (resolved to dt); the impulse is Σ F dt over "
                      "2 m* (v1 + v2). At level 1 the contact radius spans two cells, and t_c is 8 % long, as "
                      "for the single ball on its plane.") + "</p>")
    nums = {"rows": [{k: v for k, v in r.items() if k not in ("t", "force", "momentum")} for r in rows],
            "computed": computed,
            "seconds": seconds}
    return Entry("two_balls", text, verdict, says=SAYS, png="two_balls/two_balls_hertz.png", head=HEAD, html=body,
                 numbers=nums, section="two_balls")
