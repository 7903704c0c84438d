"""Plan entries of PMI sizes of radii and spheres (:mod:`.pmi_plan`, :mod:`.size_features`):
``Size_Radius`` on cylindrical faces (each coaxial group of one radius), on a sphere or on a
torus (a fillet about an axis: its tube's radius),
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
            # a fillet: tubes about an axis (tori), and balls where they meet (spheres)
            tori, rest = _tori(ctx.model, other, ctx.size) if t == "Size_Radius" else ([], [])
            try:
                balls = _spheres(ctx.model, rest) if tori else None
            except ValueError:
                balls = None
            if balls is None:
                kinds = sorted({ctx.feats[f].kind for f in other})
                return [], (f"{t} on faces that are not cylinders, spheres or tori "
                            f"({', '.join(kinds)})")
            groups += [("torus", g) for g in tori] + [("sphere", g) for g in balls]
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


def _tori(model, faces, size: float) -> tuple[list[list[int]], list[int]]:
    """(the faces that are tori, grouped by their torus: a fillet's faces about one axis;
    the faces that are not) (:func:`.size_features.cad_torus`)."""
    import numpy as np

    from .size_features import cad_torus

    tol = 1e-6 * size
    groups: list = []
    rest = []
    for f in faces:
        t = cad_torus(model, [f])
        if t is None:
            rest.append(f)
            continue
        for g in groups:
            u = g[0]
            if (np.linalg.norm(t.center - u.center) <= tol and abs(abs(t.axis @ u.axis) - 1)
                    <= 1e-9 and abs(t.major_radius - u.major_radius) <= tol
                    and abs(t.minor_radius - u.minor_radius) <= tol):
                g[1].append(f)
                break
        else:
            groups.append((t, [f]))
    return [g[1] for g in groups], rest
