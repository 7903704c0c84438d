"""Plan entries of a PMI ``Symmetry`` (:mod:`.pmi_plan`, :mod:`.symmetry`): the two opposite
planar sides of a tab or slot, in a DRF whose datums include a centre plane (a ``midplane``
datum: the two sides of another width) on which the CAD centres the feature."""
from __future__ import annotations

import numpy as np

__all__ = ["symmetry_entries"]


def symmetry_entries(item, ctx, faces, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a ``Symmetry`` on ``faces`` (model numbers)."""
    from .pmi_plan import _item_drf, unapplied_modifiers
    from .position_zones import width_sides

    if item["value_type"] != "None" or item["zone_modifier"] != "None":
        return [], (f"a symmetry with a {item['value_type']} zone or a {item['zone_modifier']} "
                    "zone modifier (two parallel planes only)")
    why = unapplied_modifiers(item)
    if why:
        return [], why
    if not item["datums"]:
        return [], "a symmetry without a datum centre plane"
    try:
        _, _, u, centre, _, _ = width_sides(ctx.feats, faces)
    except ValueError as exc:
        return [], f"{exc} (symmetry is of a width's median points)"
    names, r = _item_drf(item, ctx)
    if names is None:
        return [], r or "no datum reference frame"
    for n in names:
        spec = ctx.datum_specs[n]
        if spec.get("kind") != "midplane":
            continue
        f = [int(s.split(":")[1]) for s in spec["faces"]]
        _, _, ud, cd, _, _ = width_sides(ctx.feats, f)
        if abs(abs(float(ud @ u)) - 1.0) < 1e-6 and \
                abs(float(ud @ u) * cd - centre) <= 1e-6 * ctx.size + 1e-6:
            return [{"name": ctx.name(f"{item['id']}_symmetry"), "type": "symmetry",
                     "faces": [f"face:{i}" for i in faces], "tol": item["value"],
                     "datums": names, "pmi": src}], ""
    return [], (f"no datum centre plane of {'|'.join(names)} is the feature's CAD centre plane "
                f"(at {centre:.4f} mm along {np.round(u, 6).tolist()})")
