"""The maximum tolerance of a geometric tolerance with a material modifier (ASME Y14.5-2009
§7.3.4: "MAX" in the frame caps tolerance + bonus), read from the STEP text: AP242 writes it as
``GEOMETRIC_TOLERANCE_WITH_MAXIMUM_TOLERANCE(#measure)`` in the tolerance's complex entity.
OpenCASCADE's XCAF reader (7.x) returns 0 from ``GetMaxValueModifier()`` for the complex
entities with modifiers of NIST FTC 07 (``GEOMETRIC_TOLERANCE ... _WITH_DATUM_REFERENCE ...
_WITH_MAXIMUM_TOLERANCE ... _WITH_MODIFIERS ... POSITION_TOLERANCE``), so the value is read
here and matched to the tolerances XCAF read as :mod:`.step_composite` matches composites (by
type, magnitude and number of datums, and name when both have one).

>>> text = ("#1=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.04),#3);\\n"
...         "#2=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.045),#3);\\n"
...         "#4=( GEOMETRIC_TOLERANCE('GP6','',#1,#6) "
...         "GEOMETRIC_TOLERANCE_WITH_MAXIMUM_TOLERANCE(#2) POSITION_TOLERANCE() );")
>>> [(s['name'], s['value'], s['max_value']) for s in max_tolerances_of_text(text)]
[('GP6', 0.04, 0.045)]
"""
from __future__ import annotations

import re

from .step_composite import _MEAS, _segment
from .step_text import StepText, step_text

__all__ = ["max_tolerances_of_text", "apply_max_tolerances"]

_MAX = re.compile(r"GEOMETRIC_TOLERANCE_WITH_MAXIMUM_TOLERANCE\s*\(\s*#(\d+)", re.I)


def max_tolerances_of_text(text: str) -> list:
    """Every geometric tolerance of the STEP ``text`` (:func:`.step_composite._segment`'s
    fields) with ``max_value`` (file unit; 0.0 without a maximum tolerance)."""
    return _max_tolerances(StepText(text))


def _max_tolerances(st: StepText) -> list:
    ents, out = st.entities, []
    for k, body in ents.items():
        if "GEOMETRIC_TOLERANCE" not in body.upper():
            continue
        seg = _segment(ents, k)
        if seg is None:
            continue
        m = _MAX.search(body)
        meas = _MEAS.search(ents.get(int(m.group(1)), "")) if m else None
        seg["max_value"] = (float(meas.group(1).replace("D", "E").replace("d", "e"))
                            if meas else 0.0)
        out.append(seg)
    return out


def apply_max_tolerances(path, tolerances, scale: float = 1.0) -> list:
    """Set ``max_value`` (mm; ``scale``: mm per file unit) on the ``tolerances`` XCAF read
    (:func:`.pmi.read_pmi`'s dicts) whose maximum it left at 0 and the file gives: the file's
    tolerances that match one (type, magnitude, number of datums, name when both have one)
    must agree on the maximum, else it is left out and reported (the file is read once:
    :func:`.step_text.step_text`).  Returns the ids set and
    the ambiguities as ``[(id, reason)]``."""
    st = step_text(path)
    if not st.mentions("GEOMETRIC_TOLERANCE_WITH_MAXIMUM_TOLERANCE"):
        return [], []
    from .step_composite import _matches

    segs = _max_tolerances(st)
    done, odd = [], []
    for t in tolerances:
        if t.get("max_value", 0.0) > 0.0:
            continue
        cand = [s for s in segs if _matches(s, t, scale)
                and (not s["name"] or not t.get("name") or s["name"] == t["name"])]
        vals = {s["max_value"] for s in cand}
        if not cand or vals == {0.0}:
            continue
        if len(vals) > 1:
            odd.append((t["id"], f"{len(cand)} tolerances of the file match it with maxima "
                                 f"{sorted(v * scale for v in vals)}"))
            continue
        t["max_value"] = float(vals.pop() * scale)
        done.append(t["id"])
    return done, odd
