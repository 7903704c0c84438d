"""A STEP file's DATA section as entities by id, read and parsed once for every reader of it.

The PMI read looks at the STEP text for what OpenCASCADE's XCAF reader leaves out: the
declared tolerances and dimensions (:mod:`.pmi_text`), composite frames (:mod:`.step_composite`),
maximum tolerances (:mod:`.step_maxtol`) and the length unit (:mod:`.step_units`).  Each used to
read and tokenize the whole file (NIST FTC 10: 1.9 MB, four reads and five parses per
``plan_from_pmi``).  :func:`step_text` reads a file once and keeps the last one read, keyed by its
path, size and modification time (a changed file is read again); :func:`clear` drops it (the
PMI read does at its end, so that a long-lived importer process does not hold a parsed file).

Also here: the one table of geometric tolerance types (:data:`GT_TYPES`, STEP entity ->
OpenCASCADE's type name) the readers share.

>>> t = StepText("ISO-10303-21;HEADER;FILE_NAME('a;b');ENDSEC;DATA;\\n"
...              "#1=FLATNESS_TOLERANCE('F;1','',#9,#5);\\n#5=SHAPE_ASPECT('','',#12,.T.);")
>>> sorted(t.entities), t.entities[1]
([1, 5], "FLATNESS_TOLERANCE('F;1','',#9,#5)")
>>> t.calls(1)["FLATNESS_TOLERANCE"][:2]
["'F;1'", "''"]
"""
from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = ["GT_TYPES", "GT_KINDS", "StepText", "step_text", "clear"]

#: STEP AP242 tolerance entity -> OpenCASCADE's type name (XCAFDimTolObjects_GeomToleranceType_)
GT_TYPES = {
    "ANGULARITY_TOLERANCE": "Angularity", "CIRCULAR_RUNOUT_TOLERANCE": "CircularRunout",
    "COAXIALITY_TOLERANCE": "Coaxiality", "CONCENTRICITY_TOLERANCE": "Concentricity",
    "CYLINDRICITY_TOLERANCE": "Cylindricity", "FLATNESS_TOLERANCE": "Flatness",
    "LINE_PROFILE_TOLERANCE": "ProfileOfLine", "PARALLELISM_TOLERANCE": "Parallelism",
    "PERPENDICULARITY_TOLERANCE": "Perpendicularity", "POSITION_TOLERANCE": "Position",
    "ROUNDNESS_TOLERANCE": "CircularityOrRoundness", "STRAIGHTNESS_TOLERANCE": "Straightness",
    "SURFACE_PROFILE_TOLERANCE": "ProfileOfSurface", "SYMMETRY_TOLERANCE": "Symmetry",
    "TOTAL_RUNOUT_TOLERANCE": "TotalRunout",
}
#: the same without ``_TOLERANCE`` (``POSITION`` -> ``Position``): the kind of a complex entity
GT_KINDS = {k[:-len("_TOLERANCE")]: v for k, v in GT_TYPES.items()}

_STR = r"'(?:[^']|'')*'"
#: one entity instance: ``#id = body;`` where the body may hold quoted strings with ';' (runs
#: of plain characters, then quoted strings each followed by such a run: the same matches as
#: ``((?:'(?:[^']|'')*'|[^;'])*)``, six times faster on NIST FTC 10)
ENTITY = re.compile(r"#(\d+)\s*=\s*([^;']*(?:'[^']*'[^;']*)*);")
_CALL = re.compile(r"([A-Z][A-Z0-9_]*)\s*\(")


def data_section(text: str) -> str:
    """The text after ``DATA;`` (all of it when there is none)."""
    i = text.find("DATA;")
    return text[i + 5:] if i >= 0 else text


def calls(body: str) -> dict[str, list[str]]:
    """{KEYWORD: its top-level arguments as text} of a simple or complex entity's body."""
    out, i = {}, 0
    while True:
        m = _CALL.search(body, i)
        if m is None:
            return out
        j, depth, args, cur = m.end(), 1, [], []
        while j < len(body) and depth:
            c = body[j]
            if c == "'":
                s = re.match(_STR, body[j:])
                cur.append(s.group(0))
                j += len(s.group(0))
                continue
            depth += (c == "(") - (c == ")")
            if depth == 1 and c == ",":
                args.append("".join(cur).strip())
                cur = []
            elif depth:
                cur.append(c)
            j += 1
        args.append("".join(cur).strip())
        out.setdefault(m.group(1), args if args != [""] else [])
        i = j


class StepText:
    """The DATA section of a STEP file's ``text``, parsed once.

    Attributes
    ----------
    data : str
        The text after ``DATA;``.
    entities : dict[int, str]
        Each entity instance's body (``#12=BODY;`` -> ``{12: 'BODY'}``, stripped), in file
        order; a ';' inside a quoted string does not end it.
    """

    def __init__(self, text: str):
        self.data = data_section(text)
        self.entities = {int(k): v.strip() for k, v in ENTITY.findall(self.data)}
        self._upper = None
        self._calls = {}
        #: answers derived from the text, kept with it by their readers (e.g. the length unit)
        self.memo = {}

    def calls(self, k: int) -> dict[str, list[str]]:
        """:func:`calls` of entity ``#k`` (remembered)."""
        got = self._calls.get(k)
        if got is None:
            got = self._calls[k] = calls(self.entities.get(k, ""))
        return got

    def mentions(self, word: str) -> bool:
        """Whether the DATA section holds ``word`` (any case)."""
        if self._upper is None:
            self._upper = self.data.upper()
        return word.upper() in self._upper


_LAST: dict = {}


def step_text(path) -> StepText:
    """The :class:`StepText` of a STEP file (read as latin-1), parsed once while the file is
    unchanged (same path, size and modification time); the last file read is kept."""
    p = Path(path)
    st = os.stat(p)
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    hit = _LAST.get(key)
    if hit is None:
        with open(p, "r", encoding="latin-1") as fh:
            hit = StepText(fh.read())
        _LAST.clear()
        _LAST[key] = hit
    return hit


def clear() -> None:
    """Forget the file :func:`step_text` keeps."""
    _LAST.clear()
