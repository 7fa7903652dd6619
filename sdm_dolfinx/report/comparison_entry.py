"""The method comparison's section of the report (``make figures``): the rod of GetFEM's demo, every
method of the catalogue on a grid with dt = h/2, against the closed form; the ranking, the fitted
displacement rates, the figures, and a sentence computed from them."""
import html
import time

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import problems
from sdm_dolfinx.compare import comparison as compare
from sdm_dolfinx.compare.table import html_section
from sdm_dolfinx.study.entry import Entry, Verdict

#: the report's grids: h (dt = h / 2) and T (one period of the rod: its three phases once), quick
#: (51 runs, about 20 s on one core) and full (85 runs, about 40 s)
GRIDS = {True: {"h": [1 / 10, 1 / 20, 1 / 40], "T": 3.0},
         False: {"h": [1 / 10, 1 / 20, 1 / 40, 1 / 80, 1 / 160], "T": 3.0}}
PROBLEM = "rod1d"
#: what the literature says the comparison should show
SAYS = ("Doyen, Ern, Piperno (SIAM J. Sci. Comput. 33 (2011)) on the 1-D benchmarks: every scheme's displacement "
        "converges; exact enforcement with the standard mass (Newmark, HHT) shows spurious oscillations of the "
        "contact stress, which the modified-mass methods (mass redistribution, singular dynamic method) and the "
        "velocity-level schemes avoid; penalty and Nitsche trade penetration for smoothness.")


def entry(study, runs_dir, out, comm=MPI.COMM_WORLD, say=print):
    """Run the report's comparison (resumable; collective) and return its report entry (rank 0),
    or None when the problem is not registered."""
    if PROBLEM not in problems.names():
        say(f"comparison: problem {PROBLEM} not registered: section skipped")
        return None
    t0 = time.perf_counter()
    g = GRIDS[bool(study.quick)]
    cmp = compare.make_comparison(PROBLEM, "all", g["h"], dt_ratio=0.5, T=g["T"], out=out / f"compare-{PROBLEM}",
                                  runs_dir=runs_dir / f"compare-{PROBLEM}")
    say(f"comparison of methods on {PROBLEM}: {len(cmp.jobs())} runs in {cmp.runs_dir}")
    records = compare.run_comparison(cmp, comm, say)
    data = compare.write_outputs(cmp, records, comm)
    if comm.rank != 0:
        return None
    return _entry(cmp, data, time.perf_counter() - t0)


def _finished(data, method):
    rec = data["ranking"]["methods"].get(method)
    return rec is not None and rec["status"] == "finished"


def _rate(data, method, metric="u_LinfL2"):
    fit = (data["rates"].get(method) or {}).get(metric)
    return None if not fit else fit["rate"]


def ours(data):
    """(sentence, verdict): agrees when every finished method's displacement converges (its fitted
    u_LinfL2 rate > 0), and the standard mass's exact enforcement (Newmark) oscillates more than every
    modified-mass method (oscillation index)."""
    rank = data["ranking"]
    done = [m for m in rank["order"] if _finished(data, m)]
    rates = {m: _rate(data, m) for m in done}
    converge = [m for m, r in rates.items() if r is not None and r > 0]
    osc = {m: rank["methods"][m]["values"]["oscillation_index"] for m in done}
    modified = [m for m in done if rank["methods"][m]["class"] == "modified mass" and np.isfinite(osc[m])]
    newmark = osc.get("standard-newmark")
    smoother = newmark is not None and modified and all(newmark > osc[m] for m in modified)
    refused = [m for m in rank["order"] if rank["methods"][m]["status"] in ("refused", "error")]
    text = (f"Ours (h = {rank['h']:g}, dt = {rank['dt']:g} for the ranking; rates along dt = h/2): mean-rank order "
            f"{', '.join(done[:5])}{', ...' if len(done) > 5 else ''}; fitted rates of the relative Linf(L2) "
            "displacement error: " + ", ".join(f"{m} {r:.2f}" for m, r in rates.items() if r is not None) + ". "
            + (f"Oscillation index of the contact stress: standard-newmark {newmark:.3g} against the modified-mass "
               "methods' " + ", ".join(f"{m} {osc[m]:.3g}" for m in modified) + ". " if newmark is not None else
               "standard-newmark did not run. ")
            + (f"Not run here (refused or an error; see the table): {', '.join(refused)}. " if refused else ""))
    ok_rates = len(converge) == len(done) and done
    return text, Verdict.of(ok_rates and smoother, ok_rates or smoother)


def _entry(cmp, data, seconds):
    folder = cmp.out.name
    figs = [f for names in data["figures"].values() for f in names]
    images = "".join(f"<p><img src='{folder}/{f}' alt='{html.escape(f)}'></p>" for f in figs
                     if f != "compare_convergence.png")
    table = html_section(data["ranking"], data["rates"], f"Ranking on {cmp.problem} (compare.csv, compare.json, "
                                                        f"ranking.md in {folder}/)")
    command = (f"python -m sdm_dolfinx compare --problem {cmp.problem} --methods all --h "
               + ",".join(f"1/{round(1 / h)}" for h, _ in sorted(cmp.grid, reverse=True))
               + f" --dt-ratio 0.5 --T {cmp.T:g}")
    text, verdict = ours(data)
    return Entry(f"compare-{cmp.problem}", text, verdict, says=SAYS, png=f"{folder}/compare_convergence.png",
                 head=("<h2>Which method? (not in the paper)</h2><p>Every method of the comparison's "
                       f"catalogue on GetFEM's rod against its closed form, the same grid for all; command "
                       f"<code>{html.escape(command)}</code>; {seconds:.0f} s in this invocation.</p>"),
                 html=table + images,
                 numbers={"ranking": data["ranking"], "rates": data["rates"], "seconds": seconds, "command": command})
