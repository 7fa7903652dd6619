"""One entry of the report: a figure or a study's section, what its reference (the paper, a closed
form, the literature) says, what our numbers show, and a :class:`Verdict`.

The verdict is a value, set where the comparison is computed (``Verdict.of(ok, partly)``); the
sentence that ends our paragraph ("Ours agrees.") is built from it and never read back, so that
rewording a sentence cannot change a verdict."""
import enum
from dataclasses import dataclass, field
from typing import Any, Dict, Optional

from sdm_dolfinx.errors import SdmError


class EntryError(SdmError, TypeError):
    """A report entry built with a field the report cannot use as given (a verdict that is not a
    :class:`Verdict`, an empty key, numbers that are not a dict)."""


class Verdict(enum.Enum):
    """Whether ours agrees with what the reference says; the value is the string of numbers.json's
    ``verdicts`` and of the report's summary."""
    AGREES = "agrees"
    IN_PART = "in part"
    DISAGREES = "does not agree"

    @classmethod
    def of(cls, ok, partly=False) -> "Verdict":
        """AGREES when ``ok`` holds, IN_PART when only ``partly`` does, DISAGREES otherwise (truth values)."""
        return cls.AGREES if ok else (cls.IN_PART if partly else cls.DISAGREES)

    @property
    def sentence(self) -> str:
        """The sentence that ends our paragraph in the report."""
        return {Verdict.AGREES: "Ours agrees.", Verdict.IN_PART: "Ours agrees in part.",
                Verdict.DISAGREES: "Ours does not agree."}[self]


@dataclass(frozen=True)
class Entry:
    """A report entry.

    Args:
        key: the section's id (``fig02``, ``table2``, ``friction_block``, ...).
        findings: what our numbers show, in sentences ("Ours: ..."), without the verdict's sentence.
        verdict: computed from our numbers where they are compared with the reference.
        says: what the reference says (None: the paper's statement the report holds for ``key``).
        png: the figure, relative to the report's folder.
        html: HTML shown under the figure (a table).
        numbers: every number quoted, for numbers.json.
        head: HTML opening a section of its own before the entry.
        section: the section the entry belongs to when it is not the paper's or the friction's.
    """
    key: str
    findings: str
    verdict: Verdict
    says: Optional[str] = None
    png: Optional[str] = None
    html: Optional[str] = None
    numbers: Dict[str, Any] = field(default_factory=dict)
    head: Optional[str] = None
    section: Optional[str] = None

    def __post_init__(self):
        if not isinstance(self.verdict, Verdict):
            raise EntryError(f"report entry {self.key!r}: verdict {self.verdict!r} is not one of "
                             f"{', '.join(f'Verdict.{v.name}' for v in Verdict)}")
        if not isinstance(self.key, str) or not self.key:
            raise EntryError(f"report entry: key {self.key!r} is not a non-empty string")
        if not isinstance(self.numbers, dict):
            raise EntryError(f"report entry {self.key!r}: numbers must be a dict, not {type(self.numbers).__name__}")

    @property
    def ours(self) -> str:
        """Our paragraph: the findings, then the verdict's sentence."""
        return " ".join(p for p in (self.findings.rstrip(), self.verdict.sentence) if p)
