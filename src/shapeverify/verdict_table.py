"""The verdict values and their one table: exit code, report colour, word, terminal colour and
batch severity of each (a leaf module: the CLI reads it without importing the inspection).

The rules that choose a verdict are :mod:`shapeverify.inspection.verdict`'s.  A new verdict
value is one member of :class:`Verdict` and one row of :data:`VERDICT_TABLE`; the readers (the
CLI's exit codes, the HTML, PNG and PDF reports, the history's SQL CHECK, batch's counts)
iterate or look up the table.

>>> VERDICT_TABLE[Verdict.FAIL].exit_code, verdict_style("incomplete").word
(1, 'INCOMPLETE')
>>> most_severe(["pass", "incomplete", "fail"])
'fail'
"""

from __future__ import annotations

import enum
from typing import NamedTuple

__all__ = ["Verdict", "VERDICTS", "VerdictStyle", "VERDICT_TABLE", "verdict_style", "most_severe",
           "verdict_counts"]


class Verdict(enum.StrEnum):
    """The outcome of an inspection.  A ``str`` enum: ``Verdict.PASS == "pass"``, and it prints,
    formats and serialises (JSON, SQLite) as its plain value."""

    PASS = "pass"
    FAIL = "fail"
    ERROR = "error"
    INCOMPLETE = "incomplete"


VERDICTS = tuple(v.value for v in Verdict)


class VerdictStyle(NamedTuple):
    """How a verdict is shown and signalled (one row of :data:`VERDICT_TABLE`)."""

    #: exit code of ``shapeverify inspect``
    exit_code: int
    #: colour of the reports' banner (HTML, PNG, PDF)
    colour: str
    #: the word of the banner and the terminal
    word: str
    #: the terminal's (rich) colour name
    terminal: str
    #: order of precedence in a batch: the batch exits with the code of its most severe verdict
    severity: int


#: One row per verdict value; every reader (CLI exit codes, HTML/PNG/PDF colours, the history's
#: SQL CHECK, batch's counts) iterates or looks up this table, so a new verdict is one row here.
VERDICT_TABLE: dict[str, VerdictStyle] = {
    Verdict.PASS: VerdictStyle(0, "#1b7f3b", "PASS", "green", 0),
    Verdict.FAIL: VerdictStyle(1, "#b3261e", "FAIL", "red", 2),
    Verdict.ERROR: VerdictStyle(2, "#a15c00", "ERROR", "yellow", 3),
    Verdict.INCOMPLETE: VerdictStyle(3, "#6a3d9a", "INCOMPLETE", "magenta", 1),
}


def verdict_style(verdict) -> VerdictStyle:
    """The row of :data:`VERDICT_TABLE` for ``verdict`` (a :class:`Verdict` or its string); an
    unknown value is shown grey, with the word in capitals, and exits as an error."""
    row = VERDICT_TABLE.get(str(verdict))
    if row is not None:
        return row
    err = VERDICT_TABLE[Verdict.ERROR]
    return VerdictStyle(err.exit_code, "#555555", str(verdict).upper(), "yellow", err.severity)


def most_severe(verdicts) -> str | None:
    """The most severe verdict of ``verdicts`` (:attr:`VerdictStyle.severity`; None if empty):
    a batch's exit code is its row's."""
    vs = [str(v) for v in verdicts if str(v) in VERDICT_TABLE]
    return max(vs, key=lambda v: VERDICT_TABLE[v].severity) if vs else None


def verdict_counts(verdicts) -> dict[str, int]:
    """How many of ``verdicts`` have each value of :data:`VERDICT_TABLE` (batch's counts)."""
    vs = [str(v) for v in verdicts]
    return {str(v): vs.count(str(v)) for v in VERDICT_TABLE}
