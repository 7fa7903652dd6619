"""One declaration for every value a user gives: a problem's parameters and a run's options.

A :class:`Param` declares a value once (name, default, type, bounds or choices, help, unit);
the command line's options, the TOML keys, the messages refusing a value and ``run.json`` all
derive from it. Problems declare their parameters with it (:class:`~sdm_dolfinx.problems.ProblemSpec`),
each time scheme, contact treatment and friction law declares its own options with it, and
:mod:`sdm_dolfinx.run.options` declares the run options as :class:`RunOption` (a Param with what
a run option needs besides: its CLI group, the choice it belongs to, whether a restart may change
it, whether it is part of the run's identity). Imports nothing of ours but :mod:`.errors`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Union

import numpy as np

from sdm_dolfinx.errors import SdmError, shown

#: what a declared type is: a Python type, or ``"point"``
ParamType = Union[type, str]
#: the types a parameter may have; ``point`` is a tuple of floats (its length that of the default)
PARAM_TYPES: tuple[ParamType, ...] = (float, int, str, bool, Path, "point")


class OptionError(SdmError, ValueError):
    """A value its declaration refuses (one line; several joined with '; ')."""


@dataclass(frozen=True)
class Param:
    """One declared value: a problem's parameter, or an option of a scheme, a contact treatment
    or a friction law.

    Attributes:
        name: the keyword (a Python identifier); the command-line option is ``--name`` with
            ``_`` written ``-``, as is the TOML key.
        default: the value when none is given (None: optional, e.g. a mesh file).
        help: one line for ``--help``.
        unit: the unit, for ``--help`` and ``run.json`` (``"-"`` for none).
        type: one of :data:`PARAM_TYPES` (default: the default's type, float for None).
        low, high: inclusive bounds of a number (None: unbounded); ``low_strict`` makes the
            lower bound exclusive (``> low``).
        choices: the allowed values, or a function returning them (a registry's names, read
            when a value is checked, so that what user code registers is accepted).
        flag: the option of a bool whose default is True, e.g. ``"no-obstacle"`` for
            ``with_obstacle``: giving the flag sets the value to False.
        metavar: the placeholder(s) in ``--help``.
        expect: what a valid number is, in words ("a number in [-1/3, 0]"): the message of a
            value out of type or bounds says it (None: the bounds, as ">= 1").
        optional: None is accepted and means ``default`` (an option whose owner applies its
            default when it is not given).
        required: None is refused: the value must be given (e.g. Coulomb's ``mu``).
        high_note: why ``high`` bounds the value: a value above it is refused with this reason
            (instead of ``expect``, which still describes the other refusals).
    """
    name: str
    default: Any
    help: str
    unit: str = "-"
    type: Optional[ParamType] = None
    low: Optional[float] = None
    high: Optional[float] = None
    low_strict: bool = False
    choices: Union[Iterable[Any], Callable[[], Iterable[Any]], None] = None
    flag: Optional[str] = None
    metavar: Union[str, tuple[str, ...], None] = None
    expect: Optional[str] = None
    optional: bool = False
    required: bool = False
    high_note: Optional[str] = None

    @property
    def kind(self) -> ParamType:
        if self.type is not None:
            return self.type
        if isinstance(self.default, bool):
            return bool
        if isinstance(self.default, tuple):
            return "point"
        return type(self.default) if self.default is not None else float

    @property
    def option(self) -> str:
        """The command-line option (and TOML key) without dashes."""
        return self.flag or self.name.replace("_", "-")

    def allowed(self) -> Optional[tuple[Any, ...]]:
        """The allowed values (a tuple), or None when any value of the type goes."""
        if self.choices is None:
            return None
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def check(self, value: Any, label: str) -> list[str]:
        """Messages for ``value`` out of type, bounds or choices (empty when it is fine)."""
        return [f"{label} {c}" for c in self.complaints(value)]

    def complaints(self, value: Any) -> list[str]:
        """What is wrong with ``value``, as phrases to follow its label ("must be >= 1 (got 0)")."""
        kind, choices = self.kind, self.allowed()
        if value is None:
            if self.required or (self.default is not None and not self.optional):
                return ["needs a value"]
            return []
        if kind is bool:
            return [] if isinstance(value, (bool, np.bool_)) else [f"must be true or false (got {shown(value)})"]
        if kind in (str, Path):
            if choices is not None and value not in choices:
                return [f"must be one of {', '.join(map(str, choices))} (got {shown(value)})"]
            return []
        if kind == "point":
            vals = list(value) if isinstance(value, (tuple, list, np.ndarray)) else None
            if vals is None or len(vals) != len(self.default) or not all(_finite(v) for v in vals):
                return [f"must be {len(self.default)} finite numbers (got {shown(value)})"]
            return []
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            return [self._expected(value, f"must be {'an integer' if kind is int else 'a number'} (got {shown(value)})")]
        if choices is not None:
            return [] if value in choices else [f"must be one of {', '.join(map(str, choices))} (got {shown(value)})"]
        if kind is int and not float(value).is_integer():
            return [self._expected(value, f"must be an integer (got {shown(value)})")]
        unit = f" {self.unit}" if self.unit not in ("-", "") else ""
        if self.high_note and self.high is not None and math.isfinite(float(value)) and value > self.high:
            return [f"must be at most {_num(self.high)}{unit} ({self.high_note}) (got {_num(float(value))})"]
        if not _finite(value):
            return [self._expected(value, f"must be a finite number of magnitude <= 1e150 (got {value})")]
        if self.low is not None and (value <= self.low if self.low_strict else value < self.low):
            return [self._expected(value, f"must be {'>' if self.low_strict else '>='} {_num(self.low)}{unit} "
                                          f"(got {value})")]
        if self.high is not None and value > self.high:
            return [self._expected(value, f"must be <= {_num(self.high)}{unit} (got {value})")]
        return []

    def _expected(self, value: Any, otherwise: str) -> str:
        return f"must be {self.expect} (got {shown(value)})" if self.expect else otherwise

    def convert(self, value: Any) -> Any:
        """``value`` in the declared type (after :meth:`check`)."""
        if value is None:
            return None
        kind = self.kind
        if kind == "point":
            return tuple(float(v) for v in value)
        if kind is Path:
            return Path(value)
        if kind is int:
            return int(value)
        if kind is float:
            return float(value)
        return value

    def parse(self, text: str) -> Any:
        """The value of command-line ``text`` (ValueError, a phrase, when it is not of the type;
        the bounds are :meth:`complaints`')."""
        kind = self.kind
        if kind is float:
            try:
                return float(text)
            except ValueError:
                raise ValueError(f"not a number: {text!r}") from None
        if kind is int:
            try:
                return int(text)
            except ValueError:
                pass
            try:
                value = float(text)
            except ValueError:
                value = math.nan
            if not (math.isfinite(value) and value.is_integer()):
                raise ValueError(f"not an integer: {text!r}")
            return int(value)
        if kind is Path:
            return Path(text)
        return text


@dataclass(frozen=True)
class RunOption(Param):
    """A run option (:mod:`sdm_dolfinx.run.options` holds the table).

    Attributes:
        noun: what a value of a choice option is, for "unknown scheme 'x'; choose one of ...".
        group: the command line's argument group.
        owner: ``(choice, value)`` for an option that belongs to one value of a choice option,
            e.g. ``("scheme", "hht")`` for ``hht_alpha`` (set by the table from the declaring
            scheme, treatment or law); None for the others.
        restart: a restart may change it (the others are the run's).
        identity: part of the run's identity: a checkpoint continues only a run with the same value.
        problem_default: a problem's declared ``defaults`` may set it (pair, scheme, dt, T).
        parse_text: text -> value for the command line and TOML, instead of :meth:`Param.parse`.
        validate: ``validate(value, label) -> [messages]`` instead of :meth:`Param.check`.
        toml: the TOML value types accepted (None: those of the type), and ``toml_expected``
            their description for a message.
    """
    noun: Optional[str] = None
    group: str = ""
    owner: Optional[tuple[str, str]] = None
    restart: bool = False
    identity: bool = False
    problem_default: bool = False
    parse_text: Optional[Callable[[str], Any]] = None
    validate: Optional[Callable[[Any, str], Iterable[str]]] = None
    toml: Optional[tuple[type, ...]] = None
    toml_expected: Optional[str] = None

    def check(self, value: Any, label: str) -> list[str]:
        if self.validate is not None:
            return list(self.validate(value, label))
        choices = self.allowed()
        if self.noun is not None and value is not None and choices is not None and value not in choices:
            return [f"unknown {self.noun} {shown(value)}; choose one of {', '.join(map(str, choices))}"]
        return super().check(value, label)

    def parse(self, text: str) -> Any:
        return self.parse_text(text) if self.parse_text is not None else super().parse(text)


def check_given(owner: str, declared: Sequence[Param], given: Mapping[str, Any],
                label: Optional[Callable[[str], str]] = None) -> list[str]:
    """Messages refusing the options ``given`` (name -> value; None: not given) to ``owner``
    (e.g. ``"scheme hht"``), which declares ``declared`` (Params): a name it does not declare,
    a value its declaration refuses, a required one missing. The one check of every scheme,
    contact treatment and friction law."""
    label = label or (lambda name: name)
    names = [p.name for p in declared]
    errors = []
    unknown = [k for k, v in given.items() if k not in names and v is not None]
    if unknown:
        takes = f"it takes {', '.join(names)}" if names else "it takes none"
        errors.append(f"{owner} has no parameter {', '.join(map(label, unknown))} ({takes})")
    for p in declared:
        value = given.get(p.name)
        if value is None and p.required:
            errors.append(f"{owner} needs {label(p.name)}")
        elif value is not None:
            errors += p.check(value, label(p.name))
    return errors


def values_of(owner: str, declared: Sequence[Param], given: Mapping[str, Any]) -> dict[str, Any]:
    """Every declared option's value: ``given`` (None: the default) after :func:`check_given`
    (OptionError, one line, otherwise)."""
    errors = check_given(owner, declared, given)
    if errors:
        raise OptionError("; ".join(errors))
    return {p.name: p.default if given.get(p.name) is None else given[p.name] for p in declared}


def _finite(v: Any) -> bool:
    try:
        return math.isfinite(float(v)) and abs(float(v)) <= 1e150   # squared in energies: stay finite
    except (TypeError, ValueError):
        return False


def _num(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)
