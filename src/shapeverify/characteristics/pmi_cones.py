"""Plan entries of a PMI ``Size_Angular`` on cones (:mod:`.pmi_plan`, :mod:`.cone_sizes`): NIST
CTC 04 DIM6, "90° ±1°" on its 30 countersinks (60 half-cone faces).  The faces are grouped
into cones (same apex, axis and half angle, :func:`.cone_sizes.cad_cone` of each face); each
cone becomes a ``cone_angle`` with the dimension's ± limits, ``angle: included`` when the
drawn nominal is the cone's apex angle, ``half`` when it is its angle to the axis.  The values
are in degrees: OpenCASCADE returns the file's plane-angle measures as written (CTC 04
declares a ``CONVERSION_BASED_UNIT('DEGREE')``: 90.0, ±1.0), and the nominal must agree with
the CAD cone's angle in degrees to 1e-3 (a radian value would not).

A ``Size_Diameter`` attached to the circles where cones meet a plane (CTC 04 DIM7, ⌀20 ±0.3)
is the countersinks' diameter at that surface: one ``cone_diameter`` per cone
(:mod:`.countersink`)."""
from __future__ import annotations

import numpy as np

__all__ = ["angular_entries", "cone_groups", "countersink_entries"]


def cone_groups(model, faces, size: float) -> tuple[list, list]:
    """([(faces of one cone, apex, axis, half angle rad)], faces that are not cones)."""
    from .cone_sizes import cad_cone

    groups, other = [], []
    tol = 1e-6 * max(size, 1.0) + 1e-9
    for f in faces:
        try:
            A, a, psi, err = cad_cone(model, [f])
        except (ValueError, np.linalg.LinAlgError):
            other.append(f)
            continue
        if not (err <= tol and 1e-3 < psi < np.pi / 2 - 1e-3):
            other.append(f)
            continue
        for g in groups:
            if (np.linalg.norm(A - g[1]) <= 1e3 * tol and float(a @ g[2]) > 1 - 1e-9
                    and abs(psi - g[3]) <= 1e-7):
                g[0].append(f)
                break
        else:
            groups.append([[f], A, a, psi])
    return groups, other


def angular_entries(item, ctx, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``Size_Angular`` dimension."""
    from .pmi_plan import _faces_ok, _mm

    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], "Size_Angular without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"size modifiers {', '.join(item['modifiers'])}"
    faces, reason = _faces_ok(item, ctx)
    if faces is None:
        return [], reason
    groups, other = cone_groups(ctx.model, faces, ctx.size)
    if other:
        kinds = sorted({ctx.feats[f].kind for f in other})
        return [], (f"Size_Angular on faces that are not cones ({', '.join(kinds)}: "
                    f"face:{other[0]}); the plan measures the angle of a cone")
    nominal = float(item["nominal"])
    out = []
    for k, (g, _, _, psi) in enumerate(groups, start=1):
        inc, half = 2 * np.degrees(psi), np.degrees(psi)
        if abs(nominal - inc) <= 1e-3:
            which = "included"
        elif abs(nominal - half) <= 1e-3:
            which = "half"
        else:
            return [], (f"the nominal angle {nominal:g} deg is neither the CAD cone's included "
                        f"angle {inc:.4f} nor its half angle {half:.4f} (face:{g[0]})")
        name = f"{item['id']}_angle" + (f"_{k}" if len(groups) > 1 else "")
        out.append({"name": ctx.name(name), "type": "cone_angle",
                    "faces": [f"face:{f}" for f in g], "angle": which,
                    "lower": _mm(item["lower"]), "upper": _mm(item["upper"]),
                    "nominal": _mm(nominal), "pmi": src})
    return out, ""


def countersink_entries(item, ctx, src, why: str) -> tuple[list, str]:
    """(plan entries, '') of a ``Size_Diameter`` attached to the circular edges where cones
    meet a plane (NIST CTC 04 DIM7, ⌀20 ±0.3 on its 30 countersinks: the countersinks'
    diameter at the surface they are cut in), one ``cone_diameter`` per cone; else ([], why)."""
    from .countersink import diameter_at_plane
    from .pmi_plan import _drawn_shift, _mm

    recs = item.get("edges") or []
    if (item["faces"] or not recs or item["lower"] is None or item["modifiers"]
            or any(r.get("curve") != "Circle" or sorted(r.get("kinds", ())) != ["Cone", "Plane"]
                   for r in recs)):
        return [], why
    pairs = [(ctx.fmap.get(r["faces"][r["kinds"].index("Cone")]),
              ctx.fmap.get(r["faces"][r["kinds"].index("Plane")])) for r in recs]
    if any(c is None or p is None for c, p in pairs):
        return [], why
    groups, other = cone_groups(ctx.model, list(dict.fromkeys(c for c, _ in pairs)), ctx.size)
    if other:
        return [], why
    nominal = float(item["nominal"])
    out = []
    for k, (g, A, a, psi) in enumerate(groups, start=1):
        at = sorted({p for c, p in pairs if c in g})
        pl = ctx.feats[at[0]]
        if len(at) != 1 or pl.kind != "plane":
            return [], f"{why} (cone face:{g[0]} meets {len(at)} faces, not one plane)"
        cad, _ = diameter_at_plane(A, a, psi, pl.center, pl.axis)
        shift = _drawn_shift(item, cad)
        if shift is None:
            return [], (f"the nominal \u2300{nominal:g} differs from the CAD countersink's "
                        f"\u2300{cad:.4f} at face:{at[0]} by more than its limits")
        name = f"{item['id']}_diameter" + (f"_{k}" if len(groups) > 1 else "")
        out.append({"name": ctx.name(name), "type": "cone_diameter",
                    "faces": [f"face:{f}" for f in g], "at": [f"face:{at[0]}"],
                    "lower": _mm(item["lower"] + shift), "upper": _mm(item["upper"] + shift),
                    "nominal": _mm(nominal), "pmi": src})
    return out, ""
