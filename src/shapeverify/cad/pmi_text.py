"""The semantic PMI a STEP file's text declares, to name what OpenCASCADE's XCAF reader leaves out.

XCAF returns a geometric tolerance or a dimension only when it can follow it to the shape; NIST
CTC 04's ``Position.3`` (a position of four threaded holes) and their ``diameter`` size are
tied to thread curves in supplemental geometry, and XCAF drops both without a word.  The plan
must not drop them too: :func:`unread_pmi` compares the tolerances and semantic dimensions the
text declares with those XCAF returned (by type and name) and lists the difference, each with the
entity that declares it and why it was most likely not read.

>>> text = '''#1=FLATNESS_TOLERANCE('Flatness.1','',#9,#5);
... #2=(GEOMETRIC_TOLERANCE('Position.3','',#9,#6) GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE((#8))
...    POSITION_TOLERANCE());
... #3=DIMENSIONAL_SIZE(#6,'diameter');
... #5=SHAPE_ASPECT('','',#12,.T.);
... #6=COMPOSITE_GROUP_SHAPE_ASPECT('Position.3','pattern of features',#12,.T.);
... #7=GEOMETRIC_ITEM_SPECIFIC_USAGE('','',#5,#13,#20);
... #20=ADVANCED_FACE('',(#21),#22,.T.);'''
>>> [(d["entity"], d["type"], d["name"]) for d in declared_pmi(text)]
[('#1', 'Flatness', 'Flatness.1'), ('#2', 'Position', 'Position.3'), ('#3', 'Size', 'diameter')]
>>> read = {"tolerances": [{"type": "Flatness", "name": "Flatness.1"}], "dimensions": []}
>>> [(u["entity"], u["kind"]) for u in unread_pmi(text, read["tolerances"], read["dimensions"])]
[('#2', 'geometric_tolerance'), ('#3', 'dimension')]
"""
from __future__ import annotations

import re
from collections import Counter, defaultdict

from .step_text import GT_TYPES, StepText, step_text

__all__ = ["declared_pmi", "unread_pmi", "unread_pmi_of_file"]

#: dimension entities: (applies_to, name, ...) for sizes; (name, description, relating,
#: related, ...) for locations
_SIZES = ("DIMENSIONAL_SIZE", "DIMENSIONAL_SIZE_WITH_PATH", "ANGULAR_SIZE")
_LOCATIONS = ("DIMENSIONAL_LOCATION", "DIMENSIONAL_LOCATION_WITH_PATH", "ANGULAR_LOCATION",
              "DIRECTED_DIMENSIONAL_LOCATION")
#: XCAF's dimensions that are presentation only (no semantic counterpart in the text)
_NOT_SEMANTIC = ("DimensionPresentation", "CommonLabel")
#: items of the model's shape a usage may point at (what XCAF attaches PMI to)
_SHAPE_ITEMS = {"ADVANCED_FACE", "FACE_SURFACE", "EDGE_CURVE", "ORIENTED_EDGE", "VERTEX_POINT",
                "MANIFOLD_SOLID_BREP", "CLOSED_SHELL", "OPEN_SHELL", "BREP_WITH_VOIDS"}
_USAGES = ("ITEM_IDENTIFIED_REPRESENTATION_USAGE", "GEOMETRIC_ITEM_SPECIFIC_USAGE")

_CALL = re.compile(r"([A-Z][A-Z0-9_]*)\s*\(")


def _text(arg: str) -> str:
    return arg[1:-1].replace("''", "'") if arg.startswith("'") else ""


def _ref(arg: str) -> int | None:
    return int(arg[1:]) if re.fullmatch(r"#\d+", arg or "") else None


def _refs(arg: str) -> list[int]:
    return [int(x) for x in re.findall(r"#(\d+)", arg or "")]


def _norm(name) -> str:
    return re.sub(r"[^0-9a-z]", "", str(name or "").casefold())


def declared_pmi(text: str) -> list[dict]:
    """Every geometric tolerance and semantic dimension the STEP ``text`` declares:
    ``{entity: '#n', kind, type, name, aspect}`` (``type``: OpenCASCADE's tolerance type, or
    ``Size`` / ``Location`` for a dimension; ``aspect``: the shape aspect it applies to)."""
    return _declared(StepText(text))


def _declared(st: StepText) -> list[dict]:
    out = []
    for k in sorted(st.entities):
        body = st.entities[k]
        # every keyword matched below holds one of these: the others need no tokenizing
        if "_TOLERANCE" not in body and "_SIZE" not in body and "_LOCATION" not in body:
            continue
        calls = st.calls(k)
        gt = next((GT_TYPES[c] for c in calls if c in GT_TYPES), None)
        if gt is not None:
            args = calls.get("GEOMETRIC_TOLERANCE") or next(
                calls[c] for c in calls if c in GT_TYPES)
            if len(args) >= 4:
                out.append({"entity": f"#{k}", "kind": "geometric_tolerance", "type": gt,
                            "name": _text(args[0]), "aspect": _ref(args[3]),
                            "with": [c for c in calls if c.startswith("GEOMETRIC_TOLERANCE_WITH")
                                     and c != "GEOMETRIC_TOLERANCE_WITH_DATUM_REFERENCE"]})
            continue
        size = next((c for c in _SIZES if c in calls and len(calls[c]) >= 2), None)
        if size is not None:
            a = calls[size]
            out.append({"entity": f"#{k}", "kind": "dimension", "type": "Size",
                        "name": _text(a[1]), "aspect": _ref(a[0])})
            continue
        loc = next((c for c in _LOCATIONS if c in calls and len(calls[c]) >= 4), None)
        if loc is not None:
            a = calls[loc]
            out.append({"entity": f"#{k}", "kind": "dimension", "type": "Location",
                        "name": _text(a[0]), "aspect": _ref(a[2])})
    return out                  # in entity order: ents is walked sorted


class _Reach:
    """What a shape aspect (with the aspects it groups) is tied to by usages."""

    def __init__(self, st: StepText):
        self.st = st
        self.ents = st.entities
        self.items, self.parts = defaultdict(list), defaultdict(list)
        for k, body in self.ents.items():
            calls = st.calls(k) if ("USAGE" in body or "SHAPE_ASPECT_RELATIONSHIP" in body) \
                else {}
            for u in _USAGES:
                a = calls.get(u)
                if a and len(a) >= 5 and _ref(a[2]) is not None:
                    self.items[_ref(a[2])].extend(_refs(a[4]))
            a = calls.get("SHAPE_ASPECT_RELATIONSHIP")
            if a and len(a) >= 4 and _ref(a[2]) is not None and _ref(a[3]) is not None:
                self.parts[_ref(a[2])].append(_ref(a[3]))

    def kinds(self, aspect) -> Counter:
        """Entity keywords of the items the aspect reaches."""
        seen, todo, out = set(), [aspect], Counter()
        while todo:
            a = todo.pop()
            if a is None or a in seen:
                continue
            seen.add(a)
            for it in self.items.get(a, ()):
                body = self.ents.get(it, "")
                m = _CALL.search(body)
                out[m.group(1) if m else "?"] += 1
            todo.extend(self.parts.get(a, ()))
        return out

    def why(self, d: dict) -> str:
        calls = self.st.calls(d["aspect"]) if d["aspect"] is not None else {}
        keyword, args = next(iter(calls.items()), ("?", []))
        label = _text(args[1]) if len(args) > 1 else ""
        head = f"its shape aspect #{d['aspect']} ({keyword}" + (f" {label!r})" if label else ")")
        kinds = self.kinds(d["aspect"])
        if not kinds:
            return head + " is tied to no geometry of the file"
        if not set(kinds) & _SHAPE_ITEMS:
            return (head + " is tied to " + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items()))
                    + " (supplemental geometry), no face or edge of the solid")
        if d.get("with"):                   # e.g. a flatness per unit area (NIST CTC 03)
            return (head + " is tied to faces, but the tolerance is also a "
                    + " and a ".join(d["with"]) + ", which OpenCASCADE does not read")
        return head + " is tied to faces or edges, but OpenCASCADE did not return it"


def unread_pmi(text: str, tolerances, dimensions) -> list[dict]:
    """The tolerances and dimensions ``text`` declares that XCAF did not return.

    ``tolerances`` / ``dimensions``: what was read (dicts with ``type`` and ``name``, the XCAF
    object's semantic name).  Matched by (type, name) for tolerances and by name for semantic
    dimensions; where several declared items share the missing key, those tied to no face or
    edge are named first; if that does not decide, the entry lists the candidates.

    Returns ``[{kind, type, name, entity, reason}]`` (``entity``: '#n', or 'one of #a, #b').
    """
    return _unread(StepText(text), tolerances, dimensions)


def _unread(st: StepText, tolerances, dimensions) -> list[dict]:
    declared = _declared(st)
    have = Counter([("geometric_tolerance", t["type"], _norm(t.get("name"))) for t in tolerances]
                   + [("dimension", "", _norm(d.get("name"))) for d in dimensions
                      if d["type"] not in _NOT_SEMANTIC])
    groups = defaultdict(list)
    for d in declared:
        key = (d["kind"], d["type"] if d["kind"] == "geometric_tolerance" else "", _norm(d["name"]))
        groups[key].append(d)
    reach, out = _Reach(st), []
    for key, ds in groups.items():
        missing = len(ds) - have.get(key, 0)
        if missing <= 0:
            continue
        loose = [d for d in ds if not set(reach.kinds(d["aspect"])) & _SHAPE_ITEMS]
        if len(loose) == missing or len(ds) == missing:
            picks = [(d, d["entity"]) for d in (loose if len(loose) == missing else ds)]
        else:
            picks = [(ds[0], "one of " + ", ".join(d["entity"] for d in ds))] * missing
        for d, entity in picks:
            what = (f"the {d['type']} tolerance {d['name']!r}" if d["kind"] == "geometric_tolerance"
                    else f"the {d['type'].lower()} dimension {d['name']!r}")
            out.append({"kind": d["kind"], "type": d["type"], "name": d["name"], "entity": entity,
                        "reason": f"OpenCASCADE's PMI reader does not return {what} (STEP entity "
                                  f"{entity}): " + reach.why(d) + "; it is not checked: inspect "
                                  "it by hand"})
    out.sort(key=lambda u: int(re.search(r"\d+", u["entity"]).group(0)))
    return out


def unread_pmi_of_file(path, tolerances, dimensions) -> list[dict]:
    """:func:`unread_pmi` of a STEP file (read as latin-1, once: :func:`.step_text.step_text`)."""
    return _unread(step_text(path), tolerances, dimensions)
