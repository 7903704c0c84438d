"""Plan entries of the PMI dimensions between two features (:mod:`.pmi_plan`): a
``Location_LinearDistance`` between two parallel planar faces becomes a ``distance``, a
``Location_Angular`` between two planar faces an ``angle`` (:mod:`.gdt_size`), each with the
dimension's nominal and ± limits.  Anything else stays unsupported, with the reason."""
from __future__ import annotations

import numpy as np

__all__ = ["between_entries"]


def _mm(x: float) -> float:
    return float(round(float(x), 9)) + 0.0


def _planes(item, ctx) -> tuple[list | None, str]:
    """([face 1, face 2] model numbers, '') or (None, why): one planar face on each side."""
    sides = []
    for key in ("faces", "faces2"):
        faces = [ctx.fmap.get(f) for f in item.get(key, [])]
        if any(f is None for f in faces):
            return None, "a face it names could not be imported (see the import's warnings)"
        sides.append(faces)
    if not sides[0] or not sides[1]:
        why = item.get("edge_reason" if not sides[0] else "edge_reason2")
        if why:
            which = "first" if not sides[0] else "second"
            return None, f"it is not between two faces (its {which} side: {why})"
        what = f"{item['other'][0]}s" if item.get("other") else "nothing"
        return None, (f"it is not between two faces (its {'first' if not sides[0] else 'second'} "
                      f"side is attached to {what})")
    if len(sides[0]) != 1 or len(sides[1]) != 1:
        return None, (f"a dimension between {len(sides[0])} and {len(sides[1])} faces (the plan's "
                      "distances and angles are between two planar faces)")
    f1, f2 = sides[0][0], sides[1][0]
    kinds = [ctx.feats[f1].kind, ctx.feats[f2].kind]
    if kinds != ["plane", "plane"]:
        return None, (f"a dimension between a {kinds[0]} and a {kinds[1]} (the plan's distances "
                      "and angles are between planar faces)")
    return [f1, f2], ""


def between_entries(item, ctx, src: dict, name) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``Location_LinearDistance`` or
    ``Location_Angular`` dimension; ``name``: the plan's unique-name function."""
    t = item["type"]
    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], f"{t} without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"dimension modifiers {', '.join(item['modifiers'])}"
    faces, why = _planes(item, ctx)
    if faces is None:
        return [], why
    a, b = ctx.feats[faces[0]], ctx.feats[faces[1]]
    nom = float(item["nominal"])
    entry = {"faces": [f"face:{f}" for f in faces], "lower": _mm(item["lower"]),
             "upper": _mm(item["upper"]), "nominal": _mm(nom), "pmi": src}
    if t == "Location_LinearDistance":
        if abs(abs(a.axis @ b.axis) - 1.0) > 1e-6:
            return [], "a distance between planar faces that are not parallel"
        cad = float(abs((b.center - a.center) @ a.axis))
        if abs(cad - nom) > 1e-4 * max(nom, 1.0) + 1e-6:
            return [], (f"the nominal distance {nom:g} differs from the CAD faces' "
                        f"{cad:.4f} mm")
        return [{"name": name(f"{item['id']}_distance"), "type": "distance", **entry}], ""
    cad = float(np.degrees(np.arccos(np.clip(a.axis @ b.axis, -1.0, 1.0))))
    if min(abs(cad - nom), abs(180.0 - cad - nom)) > 1e-3:
        return [], (f"the nominal angle {nom:g} deg is neither the CAD faces' angle {cad:.4f} "
                    "nor its supplement")
    if not 0.0 < nom < 180.0:
        return [], f"an angle of {nom:g} deg between planes (0 to 180 exclusive are measured)"
    return [{"name": name(f"{item['id']}_angle"), "type": "angle", **entry}], ""
