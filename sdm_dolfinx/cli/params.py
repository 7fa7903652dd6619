"""A problem's declared parameters (:class:`~sdm_dolfinx.problems.Param`) as command-line
options: one option per parameter, with its unit and default in ``--help``.

Options are added with ``default=SUPPRESS``: the parsed namespace holds only what the
command line (or a TOML file, through the parser's defaults) gave, so the declaration's
defaults stay the single source and a restart can tell what was asked for.
"""
import argparse
from pathlib import Path


def add_param_options(parser, spec):
    """An argument group of ``parser`` with one option per parameter of ``spec``."""
    unit_note = ""
    g = parser.add_argument_group(f"{spec.name} parameters{unit_note}")
    for p in spec.params:
        g.add_argument(f"--{p.option}", dest=p.name, default=argparse.SUPPRESS, help=_help(p), **_kind(p))
    return g


def _kind(p):
    kind = p.kind
    if kind is bool:
        return {"action": "store_false" if p.default else "store_true"}
    if kind == "point":
        return {"type": float, "nargs": len(p.default), "metavar": p.metavar or ("X", "Y", "Z")[:len(p.default)]}
    if kind is Path:
        return {"type": Path, "metavar": p.metavar or "FILE"}
    if kind is str and p.choices is not None:
        return {"choices": list(p.choices)}
    out = {"type": kind}
    if p.choices is not None:
        out["choices"] = list(p.choices)
    if p.metavar:
        out["metavar"] = p.metavar
    return out


def _help(p):
    if p.kind is bool:
        return p.help
    unit = f" {p.unit}" if p.unit not in ("-", "") else ""
    if p.default is None:
        return f"{p.help} (unit:{unit})" if unit else p.help
    default = " ".join(map(str, p.default)) if isinstance(p.default, tuple) else p.default
    return f"{p.help} (default {default}{unit})"


def param_values(args, spec):
    """The parameter values present in ``args`` (a namespace), by parameter name."""
    return {p.name: (tuple(getattr(args, p.name)) if p.kind == "point" else getattr(args, p.name))
            for p in spec.params if hasattr(args, p.name)}
