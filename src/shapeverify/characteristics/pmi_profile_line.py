"""Plan entries of a PMI profile of a line (:mod:`.pmi_plan`, :mod:`.profile_line`).

An AP242 ``ProfileOfLine`` names the surface it controls and the direction of its sections.
Two attachments are read: faces (the section direction is then not in the semantic PMI: the
item stays unsupported with that reason), or a straight line drawn on a face (NIST CTC 02
GT18): the faces are those the line lies on, and the sections are parallel to the plane that
holds the line and the face's normal at its middle (:mod:`shapeverify.cad.pmi_edges`), spread
over the face (:class:`.schema.LineProfile` ``count``).

Faces that are one plane, in a datum reference frame (NIST CTC 02 e2 GT19): a plane's line
element in any section plane across it (section normal in the face's plane) is a straight
line whose located zone is the band ``|d| <= t/2`` about the true plane (``d`` the distance
from it, the same in the section as in space since the section is square to the plane); the
sections of a line profile sweep the whole face, so the value is ``2 max |d|`` over the face
whatever the section direction.  The plan takes sections normal to the face's longest
in-plane extent, ``2 slab`` apart so that they cover the face.  A floating zone (no datums)
or a curved face does depend on the direction, which the semantic PMI does not give: those
stay unsupported."""
from __future__ import annotations

__all__ = ["line_profile_entries"]


def line_profile_entries(item, ctx, drf, why, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``ProfileOfLine`` item."""
    from .pmi_plan import _drf_reason, _item_drf, _plain_zone_reason

    recs = item.get("edges") or []
    normals = [r["section_normal"] for r in recs if r.get("section_normal")]
    on = [f for r in recs for f in (r.get("on_faces") or [])]
    if not recs or not normals or not on:
        if item["faces"] and not recs:
            return _plane_entries(item, ctx, src)
        return [], item.get("edge_reason") or "no line drawn on a face gives its sections"
    if len(normals) > 1 and any(abs(sum(a * b for a, b in zip(normals[0], n))) < 1 - 1e-6
                                for n in normals[1:]):
        return [], "its lines give sections in different directions"
    faces = [ctx.fmap.get(f) for f in dict.fromkeys(on)]
    if any(f is None for f in faces):
        return [], "a face it names could not be imported (see the import's warnings)"
    plain = _plain_zone_reason(item, " (uniform zones only)")
    if plain:
        return [], plain
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


def _plane_entries(item, ctx, src) -> tuple[list, str]:
    """A profile of a line of faces that are one plane, in a DRF (module docstring)."""
    import numpy as np

    from .features import _face_grid
    from .pmi_plan import _item_drf, _plain_zone_reason, _planes_coplanar

    faces = [ctx.fmap.get(f) for f in item["faces"]]
    if any(f is None for f in faces):
        return [], "a face it names could not be imported (see the import's warnings)"
    kinds = sorted({ctx.feats[f].kind for f in faces})
    if kinds != ["plane"] or not _planes_coplanar(ctx, faces):
        return [], ("the section direction of a profile of a line attached to faces is not "
                    f"in the file's semantic PMI (its faces are {', '.join(kinds)}, not one "
                    "plane, whose located line elements would not depend on it)")
    if not item["datums"]:
        return [], ("the section direction of a profile of a line attached to faces is not "
                    "in the file's semantic PMI, and without datums each section's zone "
                    "floats: the value depends on it")
    plain = _plain_zone_reason(item, " (uniform zones only)")
    if plain:
        return [], plain
    names, r = _item_drf(item, ctx)
    if names is None:
        return [], r or "no datum reference frame"
    G = np.concatenate([_face_grid(ctx.model.faces[f])[0] for f in faces])
    nf = np.asarray(ctx.feats[faces[0]].axis, float)
    Y = G - G.mean(axis=0)
    Y -= np.outer(Y @ nf, nf)
    w, E = np.linalg.eigh(Y.T @ Y)
    e = E[:, 2] - (E[:, 2] @ nf) * nf
    e = e / np.linalg.norm(e)
    e = e if e[int(np.argmax(np.abs(e)))] > 0 else -e
    slab = 0.5
    count = int(min(2000, np.ceil(float(np.ptp(G @ e)) / (2 * slab)) + 1))
    entry = {"name": ctx.name(f"{item['id']}_line_profile"), "type": "line_profile",
             "faces": [f"face:{f}" for f in faces], "tol": item["value"],
             "normal": [round(float(x), 12) + 0.0 for x in e], "count": count, "slab": slab,
             "datums": names,
             "pmi": {**src, "sections": "a plane's located line elements: 2 max |d| over the "
                                        "face in any section square to it; sections across "
                                        "its longest extent, covering it"}}
    return [entry], ""
