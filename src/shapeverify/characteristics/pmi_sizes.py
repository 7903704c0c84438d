"""Plan entries of PMI sizes of radii and spheres (:mod:`.pmi_plan`, :mod:`.size_features`):
``Size_Radius`` on cylindrical faces (each coaxial group of one radius) or on a sphere,
``Size_SphericalDiameter`` / ``Size_SphericalRadius`` on spheres, each with the drawing's ±
limits; and the reason of a ``Location_None`` (a dimension the file gives no value)."""
from __future__ import annotations

__all__ = ["size_entries", "LOCATION_NONE_REASON"]

#: NIST CTC 01 DIM1, DIM2 (STEP dimensional_location 'linear distance') and DIM10, DIM11
#: (dimensional_size 'diameter') have no dimensional_characteristic_representation: OpenCASCADE
#: reads them as type Location_None, value 0, no limits
LOCATION_NONE_REASON = ("Location_None: the file gives this dimension no value and no limits "
                        "(OpenCASCADE reads type None, value 0; a STEP dimensional_location or "
                        "dimensional_size without its dimensional_characteristic_representation)"
                        ": nothing to check")


def size_entries(item, ctx, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a radius / spherical size dimension."""
    from .pmi_plan import _cylinders, _drawn_shift, _faces_ok, _mm
    from .pmi_positions import _spheres
    from .size_features import cad_size

    t = item["type"]
    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], f"{t} without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"size modifiers {', '.join(item['modifiers'])}"
    faces, reason = _faces_ok(item, ctx)
    if faces is None:
        return [], reason
    size = "diameter" if t == "Size_SphericalDiameter" else "radius"
    groups = []
    if t == "Size_Radius":
        cyl, other = _cylinders(ctx.feats, ctx.model, faces)
        groups = [("cylinder", g[0]) for g in cyl]
    else:
        other = list(faces)
    if other:
        try:
            groups += [("sphere", g) for g in _spheres(ctx.model, other)]
        except ValueError:
            kinds = sorted({ctx.feats[f].kind for f in other})
            return [], (f"{t} on faces that are not cylinders or spheres ({', '.join(kinds)}: "
                        "e.g. a fillet's torus)")
    if t != "Size_Radius" and any(s != "sphere" for s, _ in groups):
        return [], f"{t} on faces that are not spherical"
    nominal = float(item["nominal"])
    out = []
    for k, (shape, g) in enumerate(groups, start=1):
        r0, _, _ = cad_size(ctx.model, g, shape)
        cad = 2 * r0 if size == "diameter" else r0
        shift = _drawn_shift(item, cad)
        if shift is None:
            return [], (f"the nominal {nominal:g} differs from the CAD {shape}'s {size} "
                        f"{cad:.4f} by more than its limits")
        name = f"{item['id']}_{size}" + (f"_{k}" if len(groups) > 1 else "")
        out.append({"name": ctx.name(name), "type": "feature_size",
                    "faces": [f"face:{f}" for f in g], "shape": shape, "size": size,
                    "lower": _mm(item["lower"] + shift), "upper": _mm(item["upper"] + shift),
                    "nominal": _mm(nominal), "pmi": src})
    return out, ""
