"""The report's section "The 1-D rod's contact point under the midpoint scheme" (not in the paper): the study
of :mod:`sdm_dolfinx.validation.rod_contact` (8 runs of the rod, NX = 20, T = 2.1: P2/P1 and P1+/P0, dt =
2e-3 and 1e-3, from the interpolant of u0 and from Pi U_0), its table, its figure and a verdict computed from
the checks of what the explanation predicts.

The rows are kept in ``runs_dir/rod_contact/rod_contact.json`` with what defines them (the pairs, time steps,
starts, NX, the end time and the package's version); a rerun with the same definition reads them. Measured: the
8 runs take 10-15 s on one core.
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
from sdm_dolfinx.validation import rod_contact as rc

ROWS_FILE = "rod_contact.json"
#: what the paper says, and what the explanation derived from it predicts (the left half of the entry)
SAYS = ("Paper, Theorem 2 and Proposition 1: the semi-discrete solution (5) conserves J^h = ½ U̇ᵀMU̇ + ½ UᵀAU − UᵀL "
        "and satisfies the persistency condition λ (Gᵀ U̇) = 0; scheme (14) constrains U^{n+1/2} and sets "
        "U^{n+1} = 2U^{n+1/2} − U^n. Derived from them (sdm_dolfinx/validation/rod_contact.py): the massless "
        "modes F = Ker B are infinitely stiff, and the midpoint rule carries their error with the factor −1 "
        "(its stability function at z = ∞), so U^n = (the semi-discrete solution) + (−1)^n e. The rod's "
        "interpolated u0 holds the strain −1/2 at its free end, which the semi-discrete solution relaxes at "
        "t = 0+ (U(0+) = Π U_0): e = U_0 − Π U_0, e(0) = h/(4√3) for P1+/P0 and h/(4√15) for P2/P1, "
        "independent of dt. In the sustained contact U^{n+1/2}(0) = 0, so U^{n+1}(0) = −U^n(0) = ±e(0) "
        "(within v dt), and the reported energy changes by exactly λ^{n+1/2}(U^{n+1}(0) − U^n(0)) per step. "
        "Started from Π U_0 the dip is below v dt / 2, and the energy is 1/8 − e(0)/4, constant within "
        "λ v dt.")
HEAD = ("<h2>The 1-D rod's contact point under the midpoint scheme (not in the paper)</h2><p>GetFEM's rod "
        "(<code>python -m sdm_dolfinx rod1d</code>, NX = 20) through its first contact phase t ∈ [1, 2): why "
        "u(0) = U^{n+1}(0) alternates ±e(0) every step and the energy column swings while the contact set does "
        "not change. The mass, the constrained iterate and the velocity update are the paper's; the "
        "alternation is the midpoint scheme's undamped massless mode, excited by the interpolated initial "
        "state. The runs start from the interpolant of u0 (as every run does) and, to check the explanation, "
        "from Π U_0 = argmin {J(U) : BU = BU_0} (the semi-discrete solution at t = 0+). Same runs as "
        "<code>python -m sdm_dolfinx.validation.rod_contact</code>; docs/results.md states what the method "
        "promises.</p>")


def key():
    """What defines the study's rows (stored rows with another definition are recomputed)."""
    return {"pairs": list(rc.PAIRS), "dts": list(rc.DTS), "starts": list(rc.STARTS), "NX": rc.NX, "T": rc.T_END,
            "version": compat.package_version()}


def read_rows(folder):
    """The stored rows of ``folder`` when their definition is :func:`key`'s, else None (not collective)."""
    try:
        stored = json.loads((Path(folder) / ROWS_FILE).read_text())
    except (OSError, ValueError):
        return None
    want = json.loads(json_text(key()))
    return stored.get("rows") if isinstance(stored, dict) and stored.get("key") == want else None


def run_study(folder, comm=MPI.COMM_WORLD, say=print):
    """The rows, read when stored, computed otherwise (collective); (rows, computed: bool)."""
    rows = comm.bcast(read_rows(folder) if comm.rank == 0 else None, root=0)
    if rows is not None:
        return rows, False
    say(f"the rod's contact point: {len(rc.PAIRS) * len(rc.DTS) * len(rc.STARTS)} runs in {folder}")
    rows = rc.study(comm=comm, say=say if comm.rank == 0 else None)
    if comm.rank == 0:
        Path(folder).mkdir(parents=True, exist_ok=True)
        atomic_write_text(Path(folder) / ROWS_FILE, json_text({"key": key(), "rows": rows}))
    comm.Barrier()
    return rows, True


def entry(study, runs_dir, out, comm=MPI.COMM_WORLD, say=print):
    """Run (unless stored) and draw the section (collective); its entry on rank 0, None elsewhere."""
    t0 = time.perf_counter()
    rows, computed = run_study(Path(runs_dir) / "rod_contact", comm, say)
    if comm.rank != 0:
        return None
    rc.write_outputs(rows, Path(out) / "rod_contact")
    return make_entry(rows, computed, time.perf_counter() - t0)


def ours(rows):
    """(sentence, verdict): agrees when every check of :func:`.rod_contact.checks` holds, in part when some do."""
    ok = rc.checks(rows)
    by = {(r["pair"], r["start"], r["dt"]): r for r in rows}
    parts = []
    for pair in rc.PAIRS:
        i = [by[(pair, "interpolant", dt)] for dt in rc.DTS]
        x = [by[(pair, "relaxed", dt)] for dt in rc.DTS]
        dips = ", ".join(f"{r['dip_max']:.3e}" for r in i)
        dts = ", ".join(f"{r['dt']:g}" for r in i)
        lo, hi = min(r["energy_contact"][0] for r in i), max(r["energy_contact"][1] for r in i)
        swing = max(max(abs(e - r["energy_0"]) for e in r["energy_contact"]) for r in x)
        parts.append(f"{pair}: from the interpolant, |u(0)| in contact {dips} at dt = {dts} against e(0) = "
                     f"{i[0]['e0_closed_form']:.3e}, energy {lo:.4f} to {hi:.4f}; from Π U_0, |u(0)| ≤ "
                     f"{max(r['dip_max'] for r in x):.1e}, energy {x[0]['energy_0']:.5f} (1/8 − e(0)/4) within {swing:.1e}")
    failed = [k for k, v in ok.items() if not v]
    text = (f"Ours (NX = {rows[0]['NX']}, midpoint): " + "; ".join(parts)
            + f". The energy identity holds to {max(r['identity'] for r in rows):.0e} at every step, and the energy "
            f"is constant to {max(r['energy_flight_drift'] for r in rows):.0e} in flight. "
            + ("Every prediction holds. " if not failed else f"Predictions that fail: {', '.join(failed)}. "))
    return text, Verdict.of(not failed, len(failed) < len(ok))


def make_entry(rows, computed, seconds):
    """The section's entry: the table, the figure, the sentence and the numbers."""
    text, verdict = ours(rows)
    body = html_table(rc.HEADER, rc.table_rows(rows)) + (
        f"<p>{'Computed' if computed else 'Read'} in {seconds:.0f} s (files in <code>rod_contact/</code>). "
        "The figure draws even and odd steps apart: the two branches of the alternation. "
        + html.escape("max |ΔE − λ Δu(0)| is the energy identity of scheme (14) at the contact point.") + "</p>")
    nums = {"rows": [{k: v for k, v in r.items() if k != "series"} for r in rows], "checks": rc.checks(rows),
            "computed": computed, "seconds": seconds}
    return Entry("rod_contact", text, verdict, says=SAYS, png="rod_contact/rod_contact.png", head=HEAD, html=body,
                 numbers=nums, section="rod")
