"""Dimension sides on supplemental (construction) geometry, which XCAF leaves unattached.

NIST CTC 04 DIM8 ("25 ±0.25", a ``DIMENSIONAL_LOCATION``) runs from two coplanar faces to
'Upper Thread Plane.1': four 270° circle arcs of radius 6 mm in a
``CONSTRUCTIVE_GEOMETRY_REPRESENTATION('supplemental geometry')`` -- the cosmetic end of four
threads, a thread depth -- and XCAF returns the location with that side empty.  From the STEP
entities: the shape aspect of each side (a composite: its components), its
``GEOMETRIC_ITEM_SPECIFIC_USAGE`` items, and whether every item lies in a constructive
geometry representation.
"""
from __future__ import annotations

import logging

logger = logging.getLogger(__name__)

__all__ = ["construction_sides", "attach_construction_sides"]


def _describe(items) -> str:
    """'Upper Thread Plane.1': 4 circle arcs of radius 6 mm (from the STEP items)."""
    from OCP.StepGeom import StepGeom_Circle, StepGeom_TrimmedCurve
    from OCP.StepShape import StepShape_GeometricSet

    names, curves = [], []
    for x in items:
        n = x.Name().ToCString() if x.Name() is not None else ""
        if n and n not in names:
            names.append(n)
        for k in range(1, x.NbElements() + 1) if isinstance(x, StepShape_GeometricSet) else ():
            curves.append(x.ElementsValue(k).Value())
    text = ", ".join(f"'{n}'" for n in names) or "unnamed items"
    circ = [c.BasisCurve() if isinstance(c, StepGeom_TrimmedCurve) else c for c in curves]
    if circ and all(isinstance(c, StepGeom_Circle) for c in circ):
        radii = sorted({round(float(c.Radius()), 6) for c in circ})
        arcs = "circle arcs" if any(isinstance(c, StepGeom_TrimmedCurve) for c in curves) \
            else "circles"
        text += (f": {len(circ)} {arcs} of radius {', '.join(f'{r:g}' for r in radii)} "
                 "(file units)")
    elif curves:
        text += f": {len(curves)} curves"
    return text


def construction_sides(caf, index) -> list[tuple[list, str]]:
    """``(faces of one side, description of the other)`` of each ``DIMENSIONAL_LOCATION``
    one side of which is only supplemental geometry (items of a constructive geometry
    representation) and the other faces of the model (model face numbers)."""
    from OCP.STEPConstruct import STEPConstruct
    from OCP.StepRepr import StepRepr_ConstructiveGeometryRepresentation

    from .pmi_iiru import location_graph

    tp, _ents, locs, rels, usages = location_graph(caf)
    if not locs:
        return []

    def uses(aspect) -> list:
        own = usages.get(id(aspect), [])
        if own:
            return own
        return [u for r in rels if r.RelatingShapeAspect() is aspect
                for u in usages.get(id(r.RelatedShapeAspect()), [])]

    def side(aspect):
        """('faces', [faces]) | ('construction', description) | (None, None)."""
        us = uses(aspect)
        if not us:
            return None, None
        if all(isinstance(u.UsedRepresentation(), StepRepr_ConstructiveGeometryRepresentation)
               for u in us):
            return "construction", _describe([u.IdentifiedItemValue(j) for u in us
                                              for j in range(1, u.NbIdentifiedItem() + 1)])
        faces = []
        for u in us:
            for j in range(1, u.NbIdentifiedItem() + 1):
                x = u.IdentifiedItemValue(j)
                s = STEPConstruct.FindShape_s(tp, x) if x is not None else None
                fs = index.of(s)[0] if s is not None and not s.IsNull() else []
                if not fs:
                    return None, None
                faces.extend(f for f in fs if f not in faces)
        return "faces", faces

    out = []
    for loc in locs:
        (ka, va), (kb, vb) = side(loc.RelatingShapeAspect()), side(loc.RelatedShapeAspect())
        if {ka, kb} == {"faces", "construction"}:
            out.append((va, vb) if ka == "faces" else (vb, va))
    return out


def attach_construction_sides(caf, index, dimensions) -> None:
    """``side2_reason`` of each linear location that XCAF gives one side only, when the file
    ties its other side to supplemental geometry (:func:`construction_sides`; matched by the
    faces of the side XCAF gives)."""
    want = [d for d in dimensions if d["type"] == "Location_LinearDistance" and d["faces"]
            and not d["faces2"] and not d["other"] and not d.get("edges")]
    if not want:
        return
    try:
        sides = construction_sides(caf, index)
    except Exception as e:      # a diagnosis beyond XCAF; the read stands without it
        logger.warning("could not follow the dimension sides on supplemental geometry: %s", e)
        return
    for d in want:
        hits = [why for faces, why in sides if set(faces) == set(d["faces"])]
        if len(set(hits)) == 1:
            d["side2_reason"] = (f"supplemental geometry ({hits[0]}), not a surface of the "
                                 "part: no scan point lies on it")
