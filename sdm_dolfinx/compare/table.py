"""The comparison's numbers in tables: fitted convergence rates and the ranking of the methods on
each metric (Markdown and HTML), from the grid's records (one per method x h x dt)."""
import html
import math

import numpy as np

from sdm_dolfinx.study.text import html_table
from sdm_dolfinx.post.metrics import CONTACT_PHASE, METRICS

#: the metrics whose convergence rate the tables show (the displacement's first)
RATE_METRICS = ("u_LinfL2", "u_LinfH1", "u_contact_L2t", "stress_contact_L2t", "energy_error_max")
#: the metrics the ranking averages (the cost metrics are shown, not averaged: cheap is not accurate)
RANKED = ("energy_error_T", "energy_error_max", "penetration_max", "u_contact_L2t", "v_contact_L2t",
          "stress_contact_L2t", "u_LinfL2", "u_LinfH1", "oscillation_index", "release_time_error")
COSTS = ("newton_per_step", "wall_per_step")
#: statuses without metrics: the problem refused the method, or the run raised an unexpected error
UNRANKED = ("refused", "error")


def _value(rec, metric):
    """A record's metric as a float: nan when missing; inf for a failed run's accuracy metrics."""
    v = rec.get(metric)
    if v is None:
        return math.inf if rec.get("status") == "failed" and metric in RANKED else math.nan
    return float(v)


def _groups(points):
    """The ways the points (h, dt, value) make a refinement path: h and dt together (a fixed
    dt/h), h at a fixed dt, dt at a fixed h; each as key -> [(size, value)]."""
    kinds = {"dt/h fixed": lambda h, dt: (f"{dt / h:.6g}", h), "h at fixed dt": lambda h, dt: (f"{dt:.6g}", h),
             "dt at fixed h": lambda h, dt: (f"{h:.6g}", dt)}
    for kind, key in kinds.items():
        groups = {}
        for h, dt, v in points:
            k, size = key(h, dt)
            groups.setdefault(k, []).append((size, v))
        yield kind, groups


def fit_rate(points):
    """The convergence rate of one method's metric: the slope of log(value) against log(size) on the
    refinement path with the most points (h with dt/h fixed first, then h at a fixed dt, then dt at
    a fixed h); None when no path has two positive finite values.

    Returns:
        dict(rate, kind, key, sizes, values) or None.
    """
    for kind, groups in _groups(points):
        best = None
        for key, pts in groups.items():
            pts = sorted((s, v) for s, v in pts if np.isfinite(v) and v > 0)
            if len(pts) >= 2 and len({s for s, _ in pts}) >= 2 and (best is None or len(pts) > len(best[1])):
                best = (key, pts)
        if best is not None:
            s, v = np.array(best[1]).T
            return {"rate": float(np.polyfit(np.log(s), np.log(v), 1)[0]), "kind": kind, "key": best[0],
                    "sizes": s.tolist(), "values": v.tolist()}
    return None


def rates(records, metrics=RATE_METRICS):
    """method -> metric -> :func:`fit_rate` over the method's finished runs."""
    out = {}
    for m in dict.fromkeys(r["method"] for r in records):
        fin = [r for r in records if r["method"] == m and r.get("status") == "finished"]
        out[m] = {k: fit_rate([(r["h"], r["dt"], _value(r, k)) for r in fin]) for k in metrics}
    return out


def finest(records):
    """The (h, dt) of the ranking: the smallest h, then the smallest dt, of the grid."""
    return min(((r["h"], r["dt"]) for r in records), key=lambda p: (p[0], p[1]))


#: values below this are round-off (a penetration of 1e-16, an energy error of 1e-13): they tie at 0
ROUNDOFF = 1e-10


def _tie(v):
    """The value a rank compares: 3 significant digits (as the table shows them), round-off as 0."""
    if not np.isfinite(v):
        return v
    return 0.0 if abs(v) < ROUNDOFF else float(f"{v:.3g}")


def ranking(records):
    """Per method at the finest (h, dt): each metric's value and rank (1 = best; equal values to the
    table's 3 digits, and round-off, tie; inf, a run that blew up, last; nan, a metric the run does not have, unranked; refused methods unranked) and the
    mean rank over :data:`RANKED`; sorted by mean rank."""
    h, dt = finest(records)
    at = [r for r in records if r["h"] == h and r["dt"] == dt]
    table = {r["method"]: {"status": r.get("status"), "reason": r.get("reason", ""), "class": r.get("class", ""),
                           "values": {k: _value(r, k) for k in METRICS}, "ranks": {},
                           "undefined": dict(r.get("undefined") or {})} for r in at}
    ranked = [m for m, e in table.items() if e["status"] not in UNRANKED]
    for k in METRICS:
        vals = {m: _tie(table[m]["values"][k]) for m in ranked if not math.isnan(table[m]["values"][k])}
        for m, v in vals.items():                            # inf (a run that blew up) last
            table[m]["ranks"][k] = 1 + sum(w < v for w in vals.values()) if np.isfinite(v) else len(vals)
    for m, e in table.items():
        rs = [e["ranks"][k] for k in RANKED if k in e["ranks"]]
        e["mean_rank"] = float(np.mean(rs)) if rs else math.inf
    order = sorted(table, key=lambda m: (table[m]["status"] in UNRANKED, table[m]["mean_rank"]))
    undefined = {}
    for e in table.values():
        for k, why in e["undefined"].items():
            undefined.setdefault(k, why)
    ranked_metrics = [k for k in RANKED if any(k in table[m]["ranks"] for m in ranked)]
    return {"h": h, "dt": dt, "order": order, "methods": table, "undefined": undefined, "ranked": ranked_metrics}


def _cell(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "blew up"
    return f"{v:.3g}"


def _rate_cell(fit):
    return "-" if not fit else f"{fit['rate']:.2f}"


def table_rows(rank, fitted):
    """Header and rows (strings) of the ranking table."""
    header = (["rank", "method", "class", "mean rank"] + [k for k in RANKED + COSTS]
              + [f"rate {k}" for k in RATE_METRICS[:3]])
    rows = []
    for i, m in enumerate(rank["order"]):
        e = rank["methods"][m]
        if e["status"] in UNRANKED:
            rows.append(["-", m, e["class"], f"{e['status']}: {e['reason']}"] + [""] * (len(header) - 4))
            continue
        cells = ["n/d" if k in e["undefined"] else f"{_cell(e['values'][k])} ({e['ranks'].get(k, '-')})"
                 for k in RANKED + COSTS]
        rows.append([str(i + 1), m, e["class"], f"{e['mean_rank']:.2f}"] + cells
                    + [_rate_cell((fitted.get(m) or {}).get(k)) for k in RATE_METRICS[:3]])
    return header, rows


def markdown(rank, fitted, title):
    """The ranking as a Markdown table (a heading, what it shows, the table, the metrics' meaning)."""
    header, rows = table_rows(rank, fitted)
    lines = [f"## {title}", "",
             f"Methods ranked by their mean rank over the {len(rank['ranked'])} accuracy metrics defined here at "
             f"h = {rank['h']:g}, dt = {rank['dt']:g} (each cell: value (rank); n/d: not defined, not ranked); "
             "rates: fitted slopes of log(error) against log(h) (see compare.json for the refinement path of each).",
             ""] + [x for line in no_contact(rank) for x in (f"**{line}**", "")] + [
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(c.replace("|", "/") for c in r) + " |" for r in rows]
    if rank["undefined"]:
        lines += ["", "Not defined (not ranked):"] + [f"- `{k}`: {why}" for k, why in rank["undefined"].items()]
    lines += ["", "Metrics:"] + [f"- `{k}`: {v}" for k, v in METRICS.items()]
    return "\n".join(lines) + "\n"


def no_contact(rank):
    """The sentence (a list of zero or one) saying that the window holds no contact, so that the
    contact-phase metrics are not ranked."""
    why = [w for k, w in rank["undefined"].items() if k in CONTACT_PHASE and w.startswith("no contact")]
    if not why:
        return []
    return [f"This comparison has {why[0]}: its contact-phase metrics ({', '.join(CONTACT_PHASE)}) are not "
            f"defined and not ranked; lengthen T to compare contact."]


def html_section(rank, fitted, title):
    """The ranking as an HTML fragment (a heading, a sentence, the table)."""
    header, rows = table_rows(rank, fitted)
    undefined = ("<p>Not defined (not ranked):</p><ul>" + "".join(
        f"<li><code>{k}</code>: {html.escape(why)}</li>" for k, why in rank["undefined"].items()) + "</ul>"
        if rank["undefined"] else "")
    return (f"<h3>{html.escape(title)}</h3><p>Ranked by the mean rank over the {len(rank['ranked'])} accuracy "
            f"metrics defined here at h = {rank['h']:g}, dt = {rank['dt']:g}; each cell is value (rank); n/d: not "
            f"defined, not ranked.</p>" + "".join(f"<p><b>{html.escape(s)}</b></p>" for s in no_contact(rank))
            + html_table(header, rows) + undefined
            + "<ul>" + "".join(f"<li><code>{k}</code>: {html.escape(v)}</li>" for k, v in METRICS.items())
            + "</ul>")


def html_page(rank, fitted, title):
    """A standalone HTML page of the ranking."""
    css = ("body{font-family:sans-serif;margin:1em}table{border-collapse:collapse}"
           "td,th{border:1px solid #bbb;padding:2px 6px;font-size:85%}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{css}</style></head><body>{html_section(rank, fitted, title)}</body></html>\n")
