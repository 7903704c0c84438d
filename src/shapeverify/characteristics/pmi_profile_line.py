"""Plan entries of a PMI profile of a line (:mod:`.pmi_plan`, :mod:`.profile_line`).

An AP242 ``ProfileOfLine`` names the surface it controls and the direction of its sections.
Two attachments are read: faces (the section direction is then not in the semantic PMI: the
item stays unsupported with that reason), or a straight line drawn on a face (NIST CTC 02
GT18): the faces are those the line lies on, and the sections are parallel to the plane that
holds the line and the face's normal at its middle (:mod:`shapeverify.cad.pmi_edges`), spread
over the face (:class:`.schema.LineProfile` ``count``)."""
from __future__ import annotations

__all__ = ["line_profile_entries"]


def line_profile_entries(item, ctx, drf, why, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``ProfileOfLine`` item."""
    from .pmi_plan import _drf_reason, _item_drf

    recs = item.get("edges") or []
    normals = [r["section_normal"] for r in recs if r.get("section_normal")]
    on = [f for r in recs for f in (r.get("on_faces") or [])]
    if not recs or not normals or not on:
        if item["faces"] and not recs:
            return [], ("the section direction of a profile of a line attached to faces is not "
                        "in the file's semantic PMI")
        return [], item.get("edge_reason") or "no line drawn on a face gives its sections"
    if len(normals) > 1 and any(abs(sum(a * b for a, b in zip(normals[0], n))) < 1 - 1e-6
                                for n in normals[1:]):
        return [], "its lines give sections in different directions"
    faces = [ctx.fmap.get(f) for f in dict.fromkeys(on)]
    if any(f is None for f in faces):
        return [], "a face it names could not be imported (see the import's warnings)"
    if item["zone_modifier"] != "None":
        return [], f"a {item['zone_modifier']} zone modifier (uniform zones only)"
    extra = [m for m in item["modifiers"] if m not in ("Free_State",)]
    if extra:
        return [], f"modifier {', '.join(extra)} is not applied by the plan"
    names = None
    if item["datums"]:
        names, r = _item_drf(item, ctx)
        if names is None:
            return [], r or _drf_reason(item, drf, why) or "no datum reference frame"
    entry = {"name": ctx.name(f"{item['id']}_line_profile"), "type": "line_profile",
             "faces": [f"face:{f}" for f in faces], "tol": item["value"],
             "normal": [round(float(x), 12) + 0.0 for x in normals[0]],
             "pmi": {**src, "attached": "a line drawn on the face: sections parallel to the "
                                        "plane of the line and the face's normal"}}
    if names:
        entry["datums"] = names
    return [entry], ""
