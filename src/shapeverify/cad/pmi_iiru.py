"""Datum features that a STEP file ties to its faces by an ``ITEM_IDENTIFIED_REPRESENTATION_USAGE``
(IIRU) that OpenCASCADE's XCAF reader does not resolve, for :mod:`shapeverify.cad.pmi`.

NIST CTC 01 (CATIA) writes datum B as::

    #35=DATUM_FEATURE('Simple Datum.2',$,#4269,.T.);
    #196=SHAPE_ASPECT_RELATIONSHIP('',$,#35,#38);          (#38: DATUM(...,'B'))
    #28=ITEM_IDENTIFIED_REPRESENTATION_USAGE('',$,#35,#643,SET_REPRESENTATION_ITEM((#854,#853)));

OpenCASCADE's STEP reader reads the typed parameter ``SET_REPRESENTATION_ITEM((...))`` of the
IIRU as one unreadable item (``IdentifiedItemValue`` is null), so XCAF leaves the datum without a
shape.  :func:`resolve_datums` follows the entities itself:

1. the shape aspects of a datum: the ``DATUM``, the datum feature its
   ``SHAPE_ASPECT_RELATIONSHIP`` names, and the components of a composite shape aspect among
   them (entities as OpenCASCADE read them);
2. the IIRUs (and ``GEOMETRIC_ITEM_SPECIFIC_USAGE``, its subtype) whose ``definition`` is one of
   those aspects: their items as OpenCASCADE read them, and -- where it could not -- the entity
   references of the item parameter read from the file's text (:func:`_usage_records`: strings
   and comments skipped), each reference looked up as an entity by its label
   (``XSControl_WorkSession::NumberFromLabel``);
3. each item entity to the shape the transfer made of it (``STEPConstruct::FindShape`` on the
   reader's ``Transfer_TransientProcess``), and that shape to the model's face numbers by shape
   identity (``_FaceIndex``, never by file order).

A datum is attached only when every item resolves to faces; otherwise it keeps a reason that
says which part did not resolve.
"""
from __future__ import annotations

import re

__all__ = ["dimension_groups", "resolve_datums"]

_USAGE = re.compile(rb"#(\d+)\s*=\s*(ITEM_IDENTIFIED_REPRESENTATION_USAGE|"
                    rb"GEOMETRIC_ITEM_SPECIFIC_USAGE)\s*\(")
_REF = re.compile(r"#(\d+)")


def _params(text: bytes, start: int) -> list[str] | None:
    """The top-level parameters of a STEP record whose ``(`` is at ``start - 1`` (strings and
    comments skipped); None when the record does not close."""
    out, depth, cur, i, n = [], 1, bytearray(), start, len(text)
    while i < n:
        c = text[i]
        if c == 0x27:                                   # a string: copied, '' is a quote
            j = i + 1
            while j < n:
                if text[j] == 0x27:
                    if j + 1 < n and text[j + 1] == 0x27:
                        j += 2
                        continue
                    break
                j += 1
            cur += text[i:j + 1]
            i = j + 1
            continue
        if c == 0x2F and text[i + 1:i + 2] == b"*":      # a comment
            j = text.find(b"*/", i + 2)
            i = n if j < 0 else j + 2
            continue
        if c == 0x28:
            depth += 1
        elif c == 0x29:
            depth -= 1
            if depth == 0:
                out.append(cur.decode("latin-1").strip())
                return out
        elif c == 0x2C and depth == 1:
            out.append(cur.decode("latin-1").strip())
            cur = bytearray()
            i += 1
            continue
        elif c == 0x3B:                                  # ';' outside a string: no close
            return None
        cur.append(c)
        i += 1
    return None


def _refs(param: str) -> list[int]:
    """Entity references of a parameter, strings removed."""
    return [int(x) for x in _REF.findall(re.sub(r"'(?:[^']|'')*'", "", param))]


def _usage_records(path) -> list[tuple[int, int, list[int]]]:
    """(label, definition label, item labels) of every IIRU / GISU record of a STEP file."""
    with open(path, "rb") as fh:
        text = fh.read()
    out = []
    for m in _USAGE.finditer(text):
        ps = _params(text, m.end())
        if ps is None or len(ps) != 5:
            continue
        d = _refs(ps[2])
        if len(d) == 1:
            out.append((int(m.group(1)), d[0], _refs(ps[4])))
    return out


def _label(x) -> str:
    n = x.Name().ToCString() if hasattr(x, "Name") and x.Name() is not None else ""
    t = type(x).__name__.split("_", 1)[-1]
    return f"{t} {n!r}" if n else t


def resolve_datums(caf, path, names, index) -> dict:
    """{datum letter: (faces, how)} for the datums ``names`` that the file ties to faces by
    IIRUs, or (None, why not) when it does but they do not resolve to faces of the model.

    Parameters
    ----------
    caf : STEPCAFControl_Reader
        The reader that transferred the file (its work session, model and transfer process).
    path : Path
        The STEP file (its text holds the IIRU items OpenCASCADE could not read).
    names : set of str
        Datum letters XCAF left without a shape.
    index : shapeverify.cad.pmi._FaceIndex
        The model's faces by identity.

    Returns
    -------
    dict
        Datums not tied by any IIRU are left out.
    """
    from OCP.STEPConstruct import STEPConstruct
    from OCP.StepAP242 import (StepAP242_DraughtingModelItemAssociation,
                               StepAP242_ItemIdentifiedRepresentationUsage)
    from OCP.StepDimTol import StepDimTol_Datum
    from OCP.StepRepr import StepRepr_CompositeShapeAspect, StepRepr_ShapeAspectRelationship

    ws = caf.Reader().WS()
    model, tp = ws.Model(), ws.TransferReader().TransientProcess()
    # kept referenced, so OCP hands back the same Python object for the same entity
    ents = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    number = {id(e): i for i, e in enumerate(ents, start=1)}

    def entity(label: int):
        k = ws.NumberFromLabel(f"#{label}")
        return ents[k - 1] if 0 < k <= len(ents) else None

    # 1. the shape aspects of each datum letter
    rels = [e for e in ents if isinstance(e, StepRepr_ShapeAspectRelationship)]
    aspects: dict = {}
    for e in ents:
        if isinstance(e, StepDimTol_Datum) and e.Identification() is not None:
            n = e.Identification().ToCString()
            if n in names:
                aspects.setdefault(n, []).append(e)
    for n, found in aspects.items():
        for r in rels:                    # the datum feature: SAR(relating feature, related datum)
            a, b = r.RelatingShapeAspect(), r.RelatedShapeAspect()
            if a is not None and b is not None and any(b is x for x in found) \
                    and not any(a is x for x in found):
                found.append(a)
        k = 0
        while k < len(found) and len(found) < 1000:     # components of composite aspects
            c = found[k]
            k += 1
            if not isinstance(c, StepRepr_CompositeShapeAspect):
                continue
            for r in rels:
                a, b = r.RelatingShapeAspect(), r.RelatedShapeAspect()
                if a is c and b is not None and not isinstance(b, StepDimTol_Datum) \
                        and not any(b is x for x in found):
                    found.append(b)

    # 2. the usages of those aspects
    usages: dict = {}                   # aspect model number -> [usage entity]
    for e in ents:
        if isinstance(e, StepAP242_ItemIdentifiedRepresentationUsage) and not isinstance(
                e, StepAP242_DraughtingModelItemAssociation):    # (a link to presentation)
            d = e.Definition().Value() if e.Definition() is not None else None
            if d is not None and id(d) in number:
                usages.setdefault(number[id(d)], []).append(e)
    wanted = {number[id(a)] for fs in aspects.values() for a in fs if id(a) in number}
    if not wanted & set(usages):
        return {}
    text_items: dict = {}               # usage model number -> item entities from the text
    for lab, dlab, items in _usage_records(path):
        d, u = entity(dlab), entity(lab)
        if d is None or u is None or number.get(id(d)) not in wanted:
            continue
        text_items[number[id(u)]] = [(i, entity(i)) for i in items]

    # 3. items -> shapes -> face numbers
    out = {}
    for n, found in aspects.items():
        us = [u for a in found for u in usages.get(number.get(id(a)), [])]
        if not us:
            continue
        faces, bad = [], []
        for u in us:
            items = [u.IdentifiedItemValue(j) for j in range(1, u.NbIdentifiedItem() + 1)]
            if any(x is None for x in items) or not items:
                got = text_items.get(number[id(u)])
                if not got:
                    bad.append(f"the item of {_label(u)} (read neither by OpenCASCADE nor "
                               "from the file's text)")
                    continue
                items = []
                for lab, x in got:
                    if x is None:
                        bad.append(f"#{lab} (no such entity)")
                    else:
                        items.append(x)
            for x in items:
                s = STEPConstruct.FindShape_s(tp, x)
                if s is None or s.IsNull():
                    bad.append(f"{_label(x)} (no shape was made of it)")
                    continue
                fs, other = index.of(s)
                if not fs:
                    bad.append(f"{_label(x)} (a shape of {other[0] if other else 'no face'} "
                               "of the model)")
                faces.extend(f for f in fs if f not in faces)
        what = ", ".join(sorted({_label(u).split(" ", 1)[0] for u in us}))
        if bad or not faces:
            out[n] = (None, f"followed from the STEP entities, not every item of its {what} "
                            f"is a face of the model: {'; '.join(bad[:3])}")
        else:
            out[n] = (faces, f"{what} of its datum feature ({len(faces)} faces, resolved "
                             "from the STEP entities)")
    return out


#: datum target types (``PLACED_DATUM_TARGET_FEATURE.description``) that OpenCASCADE's XCAF
#: reader does not read and :func:`resolve_curve_targets` follows from the STEP entities
CURVE_TARGETS = {"circular curve": "CircularCurve"}


def resolve_curve_targets(caf, names, index, edge_faces, faces) -> dict:
    """{datum letter: [target records]} of the datums ``names`` set up from datum targets whose
    type XCAF does not read (:data:`CURVE_TARGETS`: a ``'circular curve'`` -- a circle along
    which the simulator touches the part), followed from the STEP entities:

    ``SHAPE_ASPECT_RELATIONSHIP(target, DATUM)`` names the ``PLACED_DATUM_TARGET_FEATURE``;
    ``FEATURE_FOR_DATUM_TARGET_RELATIONSHIP(feature, target)`` the shape aspect of its geometry;
    that aspect's ``GEOMETRIC_ITEM_SPECIFIC_USAGE`` the curve (a ``COMPOSITE_CURVE`` of two
    half circles in NIST FTC 06); the curve's shape is the one the transfer made of it
    (``STEPConstruct::FindShape``), its edges described by :func:`.pmi_edges.edge_record`.

    Each record: ``type`` (``CircularCurve``), ``number`` (the target's id), ``faces`` ([]),
    ``other`` (['edge']), ``edges`` (the records), and for a curve whose edges are arcs of one
    circle ``at`` (its centre), ``direction`` (its axis), ``length`` (its diameter),
    ``on_faces`` (the faces every point of the circle lies on, :func:`.pmi_edges.faces_along`)
    and ``attached``; or ``target_reason`` (why not).  Datums not set up from such targets are
    left out.
    """
    from OCP.STEPConstruct import STEPConstruct
    from OCP.StepAP242 import (StepAP242_DraughtingModelItemAssociation,
                               StepAP242_ItemIdentifiedRepresentationUsage)
    from OCP.StepDimTol import StepDimTol_Datum, StepDimTol_PlacedDatumTargetFeature
    from OCP.StepRepr import (StepRepr_FeatureForDatumTargetRelationship,
                              StepRepr_ShapeAspectRelationship)
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    from .pmi_edges import circle_of, edge_record, faces_along

    model, tp = caf.Reader().WS().Model(), caf.Reader().WS().TransferReader().TransientProcess()
    ents = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    rels = [e for e in ents if isinstance(e, StepRepr_ShapeAspectRelationship)]
    usages = [e for e in ents if isinstance(e, StepAP242_ItemIdentifiedRepresentationUsage)
              and not isinstance(e, StepAP242_DraughtingModelItemAssociation)]
    out: dict = {}
    for r in rels:
        tgt, dat = r.RelatingShapeAspect(), r.RelatedShapeAspect()
        if not isinstance(tgt, StepDimTol_PlacedDatumTargetFeature) or \
                not isinstance(dat, StepDimTol_Datum):
            continue
        name = dat.Identification().ToCString() if dat.Identification() is not None else ""
        desc = tgt.Description().ToCString() if tgt.Description() is not None else ""
        if name not in names or desc not in CURVE_TARGETS:
            continue
        num = tgt.TargetId().ToCString() if tgt.TargetId() is not None else ""
        rec = {"type": CURVE_TARGETS[desc], "number": int(num) if num.isdigit() else 0,
               "faces": [], "other": ["edge"]}
        out.setdefault(name, []).append(rec)
        feats = [x.RelatingShapeAspect() for x in rels
                 if isinstance(x, StepRepr_FeatureForDatumTargetRelationship)
                 and x.RelatedShapeAspect() is tgt]
        items = [u.IdentifiedItemValue(j) for f in feats for u in usages
                 if u.Definition() is not None and u.Definition().Value() is f
                 for j in range(1, u.NbIdentifiedItem() + 1)]
        edges = []
        for x in items:
            s = STEPConstruct.FindShape_s(tp, x) if x is not None else None
            if s is None or s.IsNull():
                continue
            exp = TopExp_Explorer(s, TopAbs_EDGE)
            while exp.More():
                edges.append(exp.Current())
                exp.Next()
        if not edges:
            rec["target_reason"] = (f"its {desc} target {_label(tgt)} names no curve the "
                                    "transfer made a shape of (FEATURE_FOR_DATUM_TARGET_"
                                    "RELATIONSHIP -> GEOMETRIC_ITEM_SPECIFIC_USAGE)")
            continue
        rec["edges"] = [edge_record(e, index, edge_faces, faces) for e in edges]
        circ, why = circle_of(rec["edges"])
        if circ is None:
            rec["target_reason"] = f"its {desc} target {_label(tgt)}: {why}"
            continue
        on, off = faces_along(edges, faces)
        if off:
            rec["target_reason"] = (f"its {desc} target {_label(tgt)} (circle \u2300"
                                    f"{2 * circ['radius']:.6g} at {circ['centre']}) does not lie "
                                    f"on the part's faces (e.g. at {off[0]})")
            continue
        rec.update({"at": circ["centre"], "direction": circ["axis"],
                    "length": 2.0 * circ["radius"], "on_faces": on,
                    "attached": (f"{desc!r} target {_label(tgt)}: its curve (a circle \u2300"
                                 f"{2 * circ['radius']:.6g}) on faces "
                                 f"{', '.join(map(str, on))}, resolved from the STEP entities")})
    return out


def location_graph(caf) -> tuple:
    """``(transient process, entities, locations, relationships, usages)`` of the STEP file
    ``caf`` read: all its entities, its ``DIMENSIONAL_LOCATION`` entities, the other
    ``SHAPE_ASPECT_RELATIONSHIP`` entities, and the ``ITEM_IDENTIFIED_REPRESENTATION_USAGE``
    entities (not the draughting ones) by ``id`` of the shape aspect they define.  The keys
    are ids of the entities' Python wrappers: hold on to ``entities`` while using them
    (pybind11 hands out the same wrapper for an entity only while one is alive)."""
    from OCP.StepAP242 import (StepAP242_DraughtingModelItemAssociation,
                               StepAP242_ItemIdentifiedRepresentationUsage)
    from OCP.StepRepr import StepRepr_ShapeAspectRelationship
    from OCP.StepShape import StepShape_DimensionalLocation

    ws = caf.Reader().WS()
    model, tp = ws.Model(), ws.TransferReader().TransientProcess()
    ents = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    locs = [e for e in ents if isinstance(e, StepShape_DimensionalLocation)]
    rels = [e for e in ents if isinstance(e, StepRepr_ShapeAspectRelationship)
            and not isinstance(e, StepShape_DimensionalLocation)]
    usages: dict = {}
    for e in ents:
        if isinstance(e, StepAP242_ItemIdentifiedRepresentationUsage) and not isinstance(
                e, StepAP242_DraughtingModelItemAssociation):
            d = e.Definition().Value() if e.Definition() is not None else None
            if d is not None:
                usages.setdefault(id(d), []).append(e)
    return tp, ents, locs, rels, usages


def dimension_groups(caf, index) -> list[tuple[list, list, list]]:
    """``(faces, faces2, group)`` of each ``DIMENSIONAL_LOCATION`` whose two shape aspects are
    components of one composite shape aspect (``COMPOSITE_GROUP_SHAPE_ASPECT``): the faces of
    its two sides and of every component of that composite, as model face numbers.

    NIST CTC 03 e1 writes its thickness 'Linear Size.9' (one face against four coplanar pads
    and the datum D face) as a location between two of the five faces, which lie in one plane,
    with the five faces as the components of a composite the presentation is tied to; XCAF
    reads the location's two faces only (a distance of 0 against a nominal of 20.8 mm).
    Only groups whose every component resolves to faces are returned.
    """
    from OCP.STEPConstruct import STEPConstruct
    from OCP.StepRepr import StepRepr_CompositeShapeAspect

    tp, _ents, locs, rels, usages = location_graph(caf)
    if not locs:
        return []

    def faces_of(aspect) -> list | None:
        out = []
        for u in usages.get(id(aspect), []):
            for j in range(1, u.NbIdentifiedItem() + 1):
                x = u.IdentifiedItemValue(j)
                s = STEPConstruct.FindShape_s(tp, x) if x is not None else None
                if s is None or s.IsNull():
                    return None
                fs, _ = index.of(s)
                if not fs:
                    return None
                out.extend(f for f in fs if f not in out)
        return out or None

    def composites(aspect) -> list:
        return [r.RelatingShapeAspect() for r in rels
                if r.RelatedShapeAspect() is aspect
                and isinstance(r.RelatingShapeAspect(), StepRepr_CompositeShapeAspect)]

    out = []
    for loc in locs:
        a, b = loc.RelatingShapeAspect(), loc.RelatedShapeAspect()
        if a is None or b is None:
            continue
        common = [c for c in composites(a) if any(c is d for d in composites(b))]
        if len(common) != 1:
            continue
        parts = [r.RelatedShapeAspect() for r in rels if r.RelatingShapeAspect() is common[0]]
        fa, fb = faces_of(a), faces_of(b)
        group = [faces_of(p) for p in parts]
        if fa is None or fb is None or not group or any(g is None for g in group):
            continue
        out.append((fa, fb, list(dict.fromkeys(f for g in group for f in g))))
    return out
