"""Plan entries of the PMI dimensions between two features (:mod:`.pmi_plan`): a
``Location_LinearDistance`` between two parallel planes becomes a ``distance``, a
``Location_Angular`` between two planes an ``angle`` (:mod:`.gdt_size`) -- a side is a planar
face or several faces of one plane (NIST FTC 10 DIM8: a face against four counterbore floors
at one depth) --, each with the
dimension's nominal and ± limits; a ``Size_Thickness`` on planar faces that lie in two
parallel planes (NIST CTC 03: one face against four coplanar ones) a ``distance`` between the
two planes; a ``Location_LinearDistance`` from a plane to the circle where a hole's wall meets
its drill point (NIST FTC 06 DIM49, FTC 07 DIM5, FTC 10 DIM16: a drilled hole's depth) a
``distance`` whose second side is ``{cylinder, cone}`` (:mod:`.drill_point`).  Anything else
stays unsupported, with the reason."""
from __future__ import annotations

import numpy as np

__all__ = ["between_entries", "thickness_entries"]


def _mm(x: float) -> float:
    return float(round(float(x), 9)) + 0.0


def _edge_sides(item, ctx) -> list | None:
    """[side 1, side 2] of a linear distance a side of which is a straight edge between two
    planar faces (NIST CTC 05 DIM24, 127 ±0.2032 between the top's edges with its two side
    faces): of each such edge the face that, with the other side, makes two parallel planes
    ``nominal`` apart -- None unless exactly one choice does."""
    cands = []
    for key in ("faces", "faces2"):
        recs = item.get("edges" if key == "faces" else "edges2") or []
        if item.get(key):
            cands.append([[ctx.fmap.get(f) for f in item[key]]])
        elif len(recs) == 1 and recs[0]["curve"] == "Line" and recs[0]["kinds"] == ["Plane",
                                                                                     "Plane"]:
            cands.append([[ctx.fmap.get(f)] for f in recs[0]["faces"]])
        else:
            return None
    nom = float(item["nominal"])
    hits = []
    for s1 in cands[0]:
        for s2 in cands[1]:
            if None in s1 or None in s2 or set(s1) & set(s2):
                continue
            a, b = ctx.feats[s1[0]], ctx.feats[s2[0]]
            if (a.kind == b.kind == "plane" and abs(abs(a.axis @ b.axis) - 1.0) <= 1e-6
                    and abs(abs((b.center - a.center) @ a.axis) - nom) <= 1e-4 * max(nom, 1.0)):
                hits.append([s1, s2])
    return hits[0] if len(hits) == 1 else None


def _junction_circle(recs):
    """None, or (cylinder faces, cone faces, centre, axis, radius) of a side whose edges lie on
    the circle where a cylinder meets a cone (NIST FTC 06 DIM49: a drilled hole's depth, plane
    to where its ⌀6.35 wall meets the drill point; FTC 10 DIM16 the same circle in two halves
    and four edges of thread faces): every edge's points on the cylinder of the first
    cylinder-cone edge, in one plane square to its axis; the faces (the file's numbers) those
    of the cylinder-cone edges."""
    meet = [r for r in recs if sorted(r["kinds"]) == ["Cone", "Cylinder"]
            and len(r["cylinders"]) == 1]
    if not meet:
        return None
    (i, (c, a, rad)), = meet[0]["cylinders"].items()
    a = np.asarray(a, float)
    q = np.concatenate([np.asarray(r["points"], float) for r in recs]) - np.asarray(c, float)
    h = q @ a
    rho = np.linalg.norm(q - np.outer(h, a), axis=1)
    if np.ptp(h) > 1e-4 * rad or np.max(np.abs(rho - rad)) > 1e-3 * rad:
        return None
    cyl = list(dict.fromkeys(r["faces"][r["kinds"].index("Cylinder")] for r in meet))
    cone = list(dict.fromkeys(r["faces"][r["kinds"].index("Cone")] for r in meet))
    return cyl, cone, np.asarray(c, float) + float(np.mean(h)) * a, a, float(rad)


def _junction(recs) -> str:
    """'' or what a side is when its edges lie on the circle where a cylinder meets a cone
    (:func:`_junction_circle`)."""
    got = _junction_circle(recs)
    if got is None:
        return ""
    return (f"the circle (\u2300{2 * got[4]:.6g}) where face {got[0][0]} (Cylinder) meets face "
            f"{got[1][0]} (Cone), a drilled hole's depth to its point, measured from faces of "
            "one plane: the other side names none")


def _depth_entry(item, ctx, src: dict, name) -> tuple[list, str] | None:
    """None unless one side of a ``Location_LinearDistance`` is the circle where a hole's wall
    meets its drill point (:func:`_junction_circle`) and the other names faces; then (the
    ``distance`` entry from the plane to that circle, '') or ([], why)
    (:mod:`.drill_point`)."""
    from .drill_point import SQUARE_DEG
    from .face_groups import plane_groups

    k = 1 if item.get("faces") and not item.get("faces2") else 0
    got = _junction_circle(item.get(("edges", "edges2")[k]) or [])
    if got is None or not item.get(("faces2", "faces")[k]):
        return None
    cyl, cone, centre, axis, rad = got
    where = (f"its {('first', 'second')[k]} side: the circle (\u2300{2 * rad:.6g}) where face "
             f"{cyl[0]} (Cylinder) meets face {cone[0]} (Cone), a drilled hole's depth to its "
             "point")
    plane = [ctx.fmap.get(f) for f in item[("faces2", "faces")[k]]]
    cyl, cone = [ctx.fmap.get(f) for f in cyl], [ctx.fmap.get(f) for f in cone]
    if None in plane + cyl + cone:
        return [], "a face it names could not be imported (see the import's warnings)"
    plane = list(dict.fromkeys(plane))
    if {ctx.feats[f].kind for f in plane} != {"plane"} or \
            len(plane_groups(ctx.feats, plane, max(ctx.size, 1.0))) != 1:
        return [], (f"{where}; its other side is not one plane (the depth is measured from a "
                    "plane)")
    p = ctx.feats[plane[0]]
    ang = float(np.degrees(np.arccos(min(1.0, abs(float(p.axis @ axis))))))
    if ang > SQUARE_DEG:
        return [], (f"{where}; the plane is {ang:.3g} deg from square to the hole's axis (a "
                    f"depth is measured from a plane square to it within {SQUARE_DEG} deg)")
    nom = float(item["nominal"])
    cad = abs(float((centre - p.center) @ p.axis))
    entry = {"name": name(f"{item['id']}_distance"), "type": "distance",
             "faces": [f"face:{plane[0]}" if len(plane) == 1 else [f"face:{f}" for f in plane],
                       {"cylinder": f"face:{cyl[0]}" if len(cyl) == 1 else
                        [f"face:{f}" for f in cyl],
                        "cone": f"face:{cone[0]}" if len(cone) == 1 else
                        [f"face:{f}" for f in cone]}],
             "lower": _mm(item["lower"]), "upper": _mm(item["upper"]), "nominal": _mm(nom),
             "pmi": {**src, "attached": "the circle where the hole's wall meets its drill point"}}
    if abs(cad - nom) > 1e-4 * max(nom, 1.0) + 1e-6:
        if not item["lower"] <= cad - nom <= item["upper"]:
            return [], (f"{where}; the nominal depth {nom:g} differs from the CAD's {cad:.4f} "
                        "mm by more than its limits")
        entry["pmi"] = {**entry["pmi"], "cad_distance": _mm(cad)}
    return [entry], ""


def _planes(item, ctx) -> tuple[list | None, str]:
    """([side 1, side 2], '') or (None, why): each side one plane -- a planar face, or planar
    faces in one plane with one outward side (:func:`.face_groups.plane_groups`: a floor the
    CAD splits, four counterbore floors at one depth) -- as lists of model face numbers."""
    from .face_groups import plane_groups

    sides = []
    for key in ("faces", "faces2"):
        faces = [ctx.fmap.get(f) for f in item.get(key, [])]
        if any(f is None for f in faces):
            return None, "a face it names could not be imported (see the import's warnings)"
        sides.append(list(dict.fromkeys(faces)))
    if (not sides[0] or not sides[1]) and item["type"] == "Location_LinearDistance":
        sides = _edge_sides(item, ctx) or sides
    if not sides[0] or not sides[1]:
        why = _junction(item.get("edges" if not sides[0] else "edges2") or []) or \
            item.get("edge_reason" if not sides[0] else "edge_reason2") or \
            (item.get("side2_reason") if sides[0] else None)
        if why:
            which = "first" if not sides[0] else "second"
            return None, f"it is not between two faces (its {which} side: {why})"
        what = f"{item['other'][0]}s" if item.get("other") else "nothing"
        return None, (f"it is not between two faces (its {'first' if not sides[0] else 'second'} "
                      f"side is attached to {what})")
    for k, side in enumerate(sides):
        kinds = sorted({ctx.feats[f].kind for f in side})
        if kinds != ["plane"]:
            return None, (f"a dimension between a {ctx.feats[sides[0][0]].kind} and a "
                          f"{ctx.feats[sides[1][0]].kind} (the plan's distances and angles are "
                          "between planar faces)" if len(sides[0]) == len(sides[1]) == 1 else
                          f"its {('first', 'second')[k]} side is {len(side)} faces "
                          f"({', '.join(kinds)}); the plan's distances and angles are "
                          "between planes")
        n = len(plane_groups(ctx.feats, side, max(ctx.size, 1.0)))
        if n != 1:
            return None, (f"its {('first', 'second')[k]} side is {len(side)} planar faces in "
                          f"{n} planes (the plan's distances and angles are between two "
                          "planes)")
    return sides, ""


def between_entries(item, ctx, src: dict, name) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``Location_LinearDistance`` or
    ``Location_Angular`` dimension; ``name``: the plan's unique-name function."""
    t = item["type"]
    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], f"{t} without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"dimension modifiers {', '.join(item['modifiers'])}"
    if t == "Location_LinearDistance":
        depth = _depth_entry(item, ctx, src, name)
        if depth is not None:
            return depth
    sides, why = _planes(item, ctx)
    if sides is None:
        return [], why
    if not item["faces"] or not item["faces2"]:      # a side from a straight edge
        src = {**src, "attached": "the parallel planar faces of its straight edges"}
    a, b = ctx.feats[sides[0][0]], ctx.feats[sides[1][0]]
    nom = float(item["nominal"])
    entry = {"faces": [f"face:{s[0]}" if len(s) == 1 else [f"face:{f}" for f in s]
                       for s in sides], "lower": _mm(item["lower"]),
             "upper": _mm(item["upper"]), "nominal": _mm(nom), "pmi": src}
    if t == "Location_LinearDistance":
        if abs(abs(a.axis @ b.axis) - 1.0) > 1e-6:
            return [], "a distance between planar faces that are not parallel"
        cad = float(abs((b.center - a.center) @ a.axis))
        if abs(cad - nom) > 1e-4 * max(nom, 1.0) + 1e-6:
            if item.get("group_faces") and cad <= 1e-6 * max(float(ctx.model.size), 1.0):
                # two coplanar faces of a composite (a face and coplanar pads): the distance
                # between the two planes of the composite's faces (as a Size_Thickness)
                got, why = thickness_entries(
                    {**item, "faces": item["group_faces"], "faces2": []}, ctx, src,
                    lambda _n: name(f"{item['id']}_distance"))
                if got:
                    return got, ""
                return [], (f"the nominal distance {nom:g} is not between its two coplanar "
                            f"faces; the faces of their composite: {why}")
            if not item["lower"] <= cad - nom <= item["upper"]:
                return [], (f"the nominal distance {nom:g} differs from the CAD faces' "
                            f"{cad:.4f} mm by more than its limits")
            # the CAD's faces lie within the drawing's limits: a nominal written to the
            # drawing's places (FTC 06 DIM40: .56 +-.02 in between faces .5625 in apart);
            # measured against the drawing's nominal and limits
            entry["pmi"] = {**src, "cad_distance": _mm(cad)}
        return [{"name": name(f"{item['id']}_distance"), "type": "distance", **entry}], ""
    cad = float(np.degrees(np.arccos(np.clip(a.axis @ b.axis, -1.0, 1.0))))
    if min(abs(cad - nom), abs(180.0 - cad - nom)) > 1e-3:
        return [], (f"the nominal angle {nom:g} deg is neither the CAD faces' angle {cad:.4f} "
                    "nor its supplement")
    if not 0.0 < nom < 180.0:
        return [], f"an angle of {nom:g} deg between planes (0 to 180 exclusive are measured)"
    return [{"name": name(f"{item['id']}_angle"), "type": "angle", **entry}], ""


def _plane_groups(faces, feats, size: float) -> list[list[int]]:
    """``faces`` (planar) grouped by the plane they lie in (parallel, same offset)."""
    groups: list[list[int]] = []
    for f in faces:
        a = feats[f]
        for g in groups:
            b = feats[g[0]]
            if abs(abs(a.axis @ b.axis) - 1.0) <= 1e-6 and \
                    abs((a.center - b.center) @ b.axis) <= 1e-6 * size + 1e-6:
                g.append(f)
                break
        else:
            groups.append([f])
    return groups


def thickness_entries(item, ctx, src: dict, name) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``Size_Thickness`` dimension: its planar faces
    must lie in exactly two parallel planes, ``nominal`` apart; the entry is a ``distance``
    whose two sides are those planes (each a face or the list of its coplanar faces)."""
    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], "Size_Thickness without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"dimension modifiers {', '.join(item['modifiers'])}"
    faces = [ctx.fmap.get(f) for f in list(item.get("faces", [])) + list(item.get("faces2", []))]
    if not faces or any(f is None for f in faces):
        return [], "a face it names could not be imported (see the import's warnings)"
    faces = list(dict.fromkeys(faces))
    kinds = sorted({ctx.feats[f].kind for f in faces})
    if kinds != ["plane"]:
        return [], (f"a thickness on {', '.join(kinds)} faces (the plan measures a thickness "
                    "between two planes)")
    size = max(float(ctx.model.size), 1.0)
    groups = _plane_groups(faces, ctx.feats, size)
    if len(groups) != 2:
        return [], (f"its {len(faces)} planar faces lie in {len(groups)} planes, not in two "
                    "parallel planes")
    a, b = ctx.feats[groups[0][0]], ctx.feats[groups[1][0]]
    if abs(abs(a.axis @ b.axis) - 1.0) > 1e-6:
        return [], "a thickness between planes that are not parallel"
    nom = float(item["nominal"])
    cad = float(abs((b.center - a.center) @ a.axis))
    if abs(cad - nom) > 1e-4 * max(nom, 1.0) + 1e-6:
        return [], f"the nominal thickness {nom:g} differs from the CAD planes' {cad:.4f} mm"
    sides = [f"face:{g[0]}" if len(g) == 1 else [f"face:{f}" for f in g] for g in groups]
    return [{"name": name(f"{item['id']}_thickness"), "type": "distance", "faces": sides,
             "lower": _mm(item["lower"]), "upper": _mm(item["upper"]), "nominal": _mm(nom),
             "pmi": src}], ""
