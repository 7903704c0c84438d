"""Why an orientation tolerance with the All Around modifier on a contour is not planned
(:mod:`.pmi_plan`): the reason names the contour's faces as the drawing shows them.

NIST FTC 10 GT11 (Perpendicularity 0.25 to H, All Around, faces 177-180 with the supplemental
280/281 on 177/179): the contour of an obround, two planar sides 15 mm apart and two
half-cylinders R7.5 whose axes run along datum H's normal.  ASME Y14.5-2009 defines the
all-around symbol with profile tolerances (§8); an orientation tolerance's zone is two
parallel planes (a planar surface), a cylinder (the axis of a feature of size) or, with EACH
ELEMENT, two parallel lines (a line element) (§6).  The planar sides have the first; a
half-cylinder has none of them: two parallel planes holding a half-cylinder are at least its
radius apart (a perfect part would fail), it is not a feature of size with an axis (half of
one), and the frame gives no EACH ELEMENT.  Evaluating the planes alone would drop half the
controlled surface; a profile held to H in orientation only would also bound the contour's
form and size.  So the item stays unsupported with the contour spelled out.
"""
from __future__ import annotations

from collections import Counter

import numpy as np

__all__ = ["all_around_reason"]


def _datum_direction(item, ctx):
    """Unit direction of the item's primary datum when it is one plane (its normal), else None."""
    if not item["datums"]:
        return None
    name = sorted(item["datums"], key=lambda d: d["order"])[0]["name"]
    spec = ctx.datum_specs.get(name) or {}
    if spec.get("kind") != "plane":
        return None
    f = int(spec["faces"][0].split(":")[1])
    return np.asarray(ctx.feats[f].axis, float)


def _face_words(ctx, f, n) -> str:
    ft = ctx.feats[f]
    if ft.kind == "plane":
        rel = ("" if n is None else " square to the datum" if abs(float(ft.axis @ n)) < 1e-6
               else " parallel to the datum" if abs(abs(float(ft.axis @ n)) - 1) < 1e-6 else "")
        return f"face:{f} plane{rel}"
    if ft.kind == "cylinder":
        rel = ("" if n is None else ", axis along the datum's normal"
               if abs(abs(float(ft.axis @ n)) - 1) < 1e-6 else "")
        return f"face:{f} part-cylinder R{0.5 * float(ft.diameter):g}{rel}"
    return f"face:{f} {ft.kind}"


def all_around_reason(item, ctx, faces, reason: str) -> str:
    """``reason`` (modifier All_Around not applied) with what the contour is and why no
    orientation zone fits it (module docstring)."""
    kinds = Counter(ctx.feats[f].kind for f in faces)
    out = (reason + f": All_Around ties it to {len(faces)} faces around a contour ("
           + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) + ")")
    if not set(kinds) - {"plane"}:
        return out + "; each face's zone separately is not planned"
    n = _datum_direction(item, ctx)
    return (out + ": " + "; ".join(_face_words(ctx, f, n) for f in faces)
            + ". ASME Y14.5-2009 uses All Around with profile (§8); an orientation "
            "zone is two parallel planes (a planar surface), a cylinder (a feature of size's "
            "axis) or, with EACH ELEMENT, two lines (a line element): the part-cylinders of "
            "the contour have none of these (two planes holding one are at least its radius "
            "apart, it is no feature of size, the frame gives no EACH ELEMENT); the planar "
            "faces alone would leave the rest of the contour unchecked, and a profile held to "
            "the datum in orientation only would bound form and size too; not guessed")
