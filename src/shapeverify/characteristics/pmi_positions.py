"""Plan entries of a PMI position whose zone is not a cylinder (:mod:`.pmi_plan`,
:mod:`.position_zones`): ``Position`` without ⌀ (two parallel planes) on the two opposite
planar sides of a slot or tab, and ``Position`` with S⌀ (a sphere) on the faces of a sphere.
A round hole's axis in two parallel planes: :mod:`.pmi_axis_planes`."""
from __future__ import annotations

__all__ = ["position_zone_entries"]


def position_zone_entries(item, ctx, faces, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a planes- or sphere-zone ``Position``."""
    from .pmi_plan import _item_drf, _plain_zone_reason
    from .position_zones import width_sides

    vt = item["value_type"]
    zone = {"None": "planes", "SphericalDiameter": "sphere"}[vt]
    if zone == "planes" and faces and {ctx.feats[f].kind for f in faces} == {"cylinder"}:
        why = _plain_zone_reason(item)
        if why:
            return [], why
        from .pmi_axis_planes import axis_planes_entries

        return axis_planes_entries(item, ctx, faces, src)
    if item["material"]:
        return [], (f"material modifier {item['material']} on a position in "
                    f"{'two parallel planes' if zone == 'planes' else 'a sphere'} (bonus "
                    "tolerance only for axes)")
    why = _plain_zone_reason(item)
    if why:
        return [], why
    try:
        if zone == "planes":
            width_sides(ctx.feats, faces)
            groups = [faces]
        else:
            groups = _spheres(ctx.model, faces)
    except ValueError as exc:
        return [], str(exc)
    names = None
    if item["datums"]:
        names, r = _item_drf(item, ctx)
        if names is None:
            return [], r or "no datum reference frame"
    out = []
    for k, g in enumerate(groups, start=1):
        # a pattern of spheres (FTC 06 GT6: two balls under one tolerance): one entry each,
        # all in the same datum reference frame
        base = f"{item['id']}_position" + (f"_{k}" if len(groups) > 1 else "")
        entry = {"name": ctx.name(base), "type": "position_zone",
                 "faces": [f"face:{f}" for f in g], "tol": item["value"], "zone": zone,
                 "pmi": src}
        if names:
            entry["datums"] = names
        out.append(entry)
    return out, ""


def _spheres(model, faces) -> list:
    """The faces grouped by the sphere they lie on (each face's least-squares sphere; same
    centre and radius within 1e-6 of the radius); ValueError when a face is not spherical."""
    from .position_zones import sphere_of_faces

    groups: list = []
    for f in faces:
        c, r, _ = sphere_of_faces(model, [f])
        for g in groups:
            if abs(g[2] - r) <= 1e-6 * r and float(((g[1] - c) ** 2).sum()) ** 0.5 <= 1e-6 * r:
                g[0].append(f)
                break
        else:
            groups.append([[f], c, r])
    return [g[0] for g in groups]
