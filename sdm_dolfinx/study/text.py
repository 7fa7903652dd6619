"""Numbers in words and tables: percentages, lists, HTML tables and JSON-safe values for the report's
sentences and numbers.json (a verdict is a value: :class:`sdm_dolfinx.study.entry.Verdict`)."""
import html
import math

import numpy as np


def pct(x, digits=2):
    """A ratio as a percentage (n/a, or ∞ for a run that blew up)."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    if math.isinf(x):
        return "∞ (blew up)"
    return f"{100 * x:.{digits}g} %" if abs(100 * x) < 10 ** digits else f"{100 * x:.0f} %"


def listing(xs):
    return ", ".join(xs)


def html_table(header, rows, markup_header=False):
    """An HTML table, every cell escaped; ``markup_header``: the header cells are HTML already
    (``e<sub>y</sub>``)."""
    h = "".join(f"<th>{c if markup_header else html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def jsonable(d):
    """``d`` with string keys and Python numbers (for numbers.json)."""
    if isinstance(d, dict):
        return {str(k): jsonable(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [jsonable(v) for v in d]
    if isinstance(d, (np.floating, np.integer)):
        return d.item()
    return d
