"""Composite feature control frames of a STEP file, read from its text: AP242 links the two
segments of a composite frame by ``GEOMETRIC_TOLERANCE_RELATIONSHIP('composite', '',
#upper, #lower)`` (the relating tolerance is the upper segment, the pattern-locating one; the
related tolerance the lower, feature-relating one).  OpenCASCADE's XCAF reader (7.x) reads each
segment as a tolerance of its own and keeps no trace of the relationship, so it is read here
from the entities (as :mod:`.step_units` reads the length unit).

Each segment is described by what XCAF also reports -- the tolerance's name, its type
(``POSITION_TOLERANCE`` ... without ``_TOLERANCE``), its magnitude (the value of its
``LENGTH_MEASURE_WITH_UNIT``, in the file's unit) and the number of its datum references -- so
that :func:`match_composites` can find the pair among the tolerances XCAF read.

>>> text = ("#1=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.5),#3);\\n"
...         "#2=DATUM_SYSTEM('',$,#12,.F.,(#7,#8,#9));\\n"
...         "#4=( GEOMETRIC_TOLERANCE('Position.2','',#1,#6) "
...         "GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE((#2)) POSITION_TOLERANCE() );\\n"
...         "#5=( GEOMETRIC_TOLERANCE('Position.2','',#11,#6) "
...         "GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE((#10)) POSITION_TOLERANCE() );\\n"
...         "#10=DATUM_SYSTEM('',$,#12,.F.,(#7,#8));\\n"
...         "#11=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.3),#3);\\n"
...         "#13=GEOMETRIC_TOLERANCE_RELATIONSHIP('composite','',#4,#5);")
>>> [(r['upper']['value'], r['lower']['value'], r['lower']['n_datums'])
...  for r in composite_relations_of_text(text)]
[(1.5, 0.3, 2)]
"""
from __future__ import annotations

import re

from .step_text import GT_KINDS, StepText, step_text

__all__ = ["composite_relations_of_text", "composite_relations_of_file", "match_composites"]

_REL = re.compile(r"GEOMETRIC_TOLERANCE_RELATIONSHIP\s*\(\s*'([^']*)'\s*,\s*(?:'[^']*'|\$)\s*,"
                  r"\s*#(\d+)\s*,\s*#(\d+)\s*\)", re.I)
_GT = re.compile(r"GEOMETRIC_TOLERANCE\s*\(\s*'([^']*)'\s*,\s*(?:'[^']*'|\$)\s*,\s*#(\d+)",
                 re.I)
_KIND = re.compile(r"\b([A-Z_]+?)_TOLERANCE\s*\(", re.I)
_DREF = re.compile(r"GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE\s*\(\s*\(([^)]*)\)", re.I)
_MEAS = re.compile(r"MEASURE\s*\(\s*([-+0-9.EeDd]+)\s*\)")
_REFS = re.compile(r"#(\d+)")

#: STEP tolerance entity (without ``_TOLERANCE``) -> XCAF's type name: the shared table
XCAF_TYPE = GT_KINDS


def _segment(ents: dict, k: int) -> dict | None:
    body = ents.get(k, "")
    g = _GT.search(body)
    if g is None:
        return None
    kinds = [m.upper() for m in _KIND.findall(body)
             if m.upper() not in ("GEOMETRIC", "GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE")]
    kind = next((x for x in kinds if not x.startswith("GEOMETRIC")), None)
    meas = _MEAS.search(ents.get(int(g.group(2)), ""))
    n_datums = 0
    dr = _DREF.search(body)
    if dr is not None:
        for ref in _REFS.findall(dr.group(1)):
            sys_body = ents.get(int(ref), "")
            inner = re.search(r"\(([^()]*)\)\s*\)\s*$", sys_body)
            n_datums += len(_REFS.findall(inner.group(1))) if (
                "DATUM_SYSTEM" in sys_body.upper() and inner) else 1
    return {"entity": k, "name": g.group(1), "kind": kind,
            "type": XCAF_TYPE.get(kind or "", kind),
            "value": float(meas.group(1).replace("D", "E").replace("d", "e")) if meas else None,
            "n_datums": n_datums}


def composite_relations_of_text(text: str) -> list:
    """The composite frames of the STEP ``text``: a list of ``{'upper': seg, 'lower': seg}``
    (each seg: ``entity`` (its #id), ``name``, ``type`` (XCAF's name), ``value`` (file unit),
    ``n_datums``), in the file's order.  Other tolerance relationships are left out."""
    return _relations(StepText(text))


def _relations(st: StepText) -> list:
    ents, out = st.entities, []
    for body in ents.values():
        if "TOLERANCE_RELATIONSHIP" not in body.upper():
            continue
        m = _REL.search(body)
        if m is None or m.group(1).strip().lower() != "composite":
            continue
        up, lo = _segment(ents, int(m.group(2))), _segment(ents, int(m.group(3)))
        if up is not None and lo is not None:
            out.append({"upper": up, "lower": lo})
    return out


def composite_relations_of_file(path) -> list:
    """:func:`composite_relations_of_text` of a STEP file (read as latin-1, once:
    :func:`.step_text.step_text`); [] without relationships."""
    st = step_text(path)
    if not st.mentions("GEOMETRIC_TOLERANCE_RELATIONSHIP"):
        return []
    return _relations(st)


def _matches(seg: dict, tol: dict, scale: float) -> bool:
    if seg["type"] != tol["type"] or seg["value"] is None:
        return False
    if seg.get("name") and tol.get("name") and seg["name"] != tol["name"]:
        return False                    # the file's names (NIST FTC 07's GP15 and GP16 are
        #                                 alike in type, values and datums)
    if abs(seg["value"] * scale - tol["value"]) > 1e-9 * max(1.0, abs(tol["value"])):
        return False
    return seg["n_datums"] == len({d["name"] for d in tol.get("datums", ())})


def match_composites(relations: list, tolerances: list, scale: float = 1.0) -> list:
    """Mark the composite segments among ``tolerances`` (the dicts :func:`.pmi.read_pmi`
    returns): each pair of ``relations`` is matched by type, value (``scale``: mm per file
    unit), number of datums and the name the file gives it (where both have one), the two
    segments sharing their faces; a segment that matches no
    tolerance, or more than one, is left unmarked (and returned in the list of what could not be
    matched).  A matched tolerance gets ``composite: {'segment': 'upper' | 'lower', 'with':
    <the other's id>, 'entity': '#n'}``."""
    missed = []
    for rel in relations:
        ups = [t for t in tolerances if _matches(rel["upper"], t, scale)]
        los = [t for t in tolerances if _matches(rel["lower"], t, scale)]
        pairs = [(u, lo) for u in ups for lo in los
                 if u is not lo and sorted(u.get("faces", ())) == sorted(lo.get("faces", ()))
                 and "composite" not in u and "composite" not in lo]
        if len(pairs) != 1:
            missed.append({**rel, "reason": f"{len(pairs)} pairs of tolerances match"})
            continue
        u, lo = pairs[0]
        u["composite"] = {"segment": "upper", "with": lo["id"],
                          "entity": f"#{rel['upper']['entity']}"}
        lo["composite"] = {"segment": "lower", "with": u["id"],
                           "entity": f"#{rel['lower']['entity']}"}
    return missed
