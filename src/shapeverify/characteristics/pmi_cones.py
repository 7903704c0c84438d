"""Plan entries of a PMI ``Size_Angular`` on cones (:mod:`.pmi_plan`, :mod:`.cone_sizes`): NIST
CTC 04 DIM6, "90° ±1°" on its 30 countersinks (60 half-cone faces).  The faces are grouped
into cones (same apex, axis and half angle, :func:`.cone_sizes.cad_cone` of each face); each
cone becomes a ``cone_angle`` with the dimension's ± limits, ``angle: included`` when the
drawn nominal is the cone's apex angle, ``half`` when it is its angle to the axis.  The values
are in degrees: OpenCASCADE returns the file's plane-angle measures as written (CTC 04
declares a ``CONVERSION_BASED_UNIT('DEGREE')``: 90.0, ±1.0), and the nominal must agree with
the CAD cone's angle in degrees to 1e-3 (a radian value would not)."""
from __future__ import annotations

import numpy as np

__all__ = ["angular_entries", "cone_groups"]


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
