"""Declared values as command-line options: a problem's parameters
(:class:`~sdm_dolfinx.problems.Param`: one option per parameter, with its unit and default in
``--help``) and the run options (:mod:`sdm_dolfinx.run.options`: one option per declared run
option, in the table's groups; the registries' choices read when the parser is built).

Options are added with ``default=SUPPRESS``: the parsed namespace holds only what the
command line (or a TOML file, through the parser's defaults) gave, so the declaration's
defaults stay the single source and a restart can tell what was asked for.
"""
import argparse
from pathlib import Path

from sdm_dolfinx.run import options as run_options


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


# ------------------------------------------------------------------------------ run options
def add_run_options(parser, defaults, before=None, after=None):
    """One argument group per group of the run options' table (:mod:`sdm_dolfinx.run.options`),
    with one option per declared run option, the registered schemes', contact treatments' and
    friction laws' included; ``defaults`` are the problem's (pair, scheme, dt, T, time_unit).
    ``before``/``after``: group title -> ``f(group)`` adding the command's own options there."""
    for title in run_options.GROUPS:
        g = parser.add_argument_group(title)
        if before and title in before:
            before[title](g)
        for o in run_options.declarations():
            if o.group == title:
                g.add_argument(f"--{o.option}", dest=o.name, default=argparse.SUPPRESS, help=_run_help(o, defaults),
                               **_run_kind(o))
        if after and title in after:
            after[title](g)


def run_option_values(args):
    """The run options present in ``args`` (a namespace), flat, by name."""
    return {name: getattr(args, name) for name in run_options.names() if hasattr(args, name)}


def _run_kind(o):
    choices = o.allowed()
    if o.kind is str and choices is not None and o.parse_text is None:
        return {"choices": list(choices), **({"metavar": o.metavar} if o.metavar else {})}
    return {"type": value_of_text(o), **({"metavar": o.metavar} if o.metavar else {})}


def value_of_text(o):
    """The argparse type of the run option ``o``: its declaration parses the text and checks the
    value (a TOML value is given as text too: ``toml_types`` are the TOML types it accepts)."""
    def parse(text):
        try:
            value = o.parse(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
        bad = o.complaints(value) if o.validate is None else []
        if bad:
            raise argparse.ArgumentTypeError(bad[0])
        return value
    numbers = {int: ((int,), "an integer"), float: ((int, float), "a number")}
    parse.toml_types, parse.toml_expected = numbers.get(o.kind, ((str,), "a string"))
    if o.toml is not None:
        parse.toml_types, parse.toml_expected = o.toml, o.toml_expected
    parse.__name__ = o.name
    return parse


def _run_help(o, defaults):
    if o.owner is not None:
        kind, owner = o.owner
        default = "" if o.default is None else f"; default {o.default}"
        return f"{o.help} (--{kind} {owner}{default})"
    unit = defaults.get("time_unit", "")
    choices = o.allowed()
    default = defaults.get(o.name, o.default) if o.problem_default else o.default
    return o.help.format(choices=", ".join(map(str, choices or ())), default=default, unit=f", {unit}" if unit else "")
