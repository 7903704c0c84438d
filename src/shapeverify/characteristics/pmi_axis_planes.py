"""Plan entry of a PMI ``Position`` without ⌀ on a round hole: the hole's axis in two
parallel planes (ASME Y14.5-2009 §7.7.3, bidirectional positional tolerancing).

The zone's direction across the axis is not in the semantic PMI (no zone orientation, no
affected plane); the standard puts it in the drawing: the frame is attached to a dimension
line and applies along it.  :func:`shapeverify.cad.step_frame_direction.
frame_dimension_direction` reads that from the file's presentation (NIST CTC 03 'Position.8':
on the dimension line of the hole's size drawn across it along y).  The entry is a
``position`` with ``zone: planes`` and ``direction`` (:mod:`.gdt`: twice the largest offset
of the mating axis' ends from the true position along ``direction``, with the material
modifier's bonus); ``pmi.zone_direction`` says where the direction came from.  Without such a
drawing the item stays unsupported, saying what is missing.
"""
from __future__ import annotations

__all__ = ["axis_planes_entries"]


def axis_planes_entries(item, ctx, faces, src) -> tuple[list, str]:
    """(plan entries, '') or ([], reason) of a planes-zone ``Position`` on cylinder faces."""
    from ..cad.step_frame_direction import frame_dimension_direction
    from ..cad.step_units import length_unit_of_file
    from .pmi_plan import _cylinders, _item_drf, _mm, _size_of

    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    if other or len(groups) != 1:
        return [], (f"a position in two parallel planes on {len(groups)} cylinder axes"
                    + (f" and {len(other)} other faces" if other else "")
                    + " (one hole's axis is planned)")
    g, centre, axis, dia, _ = groups[0]
    path = ctx.pmi.get("source")
    if not path or not item.get("name"):
        return [], "a hole's axis in two parallel planes: the file or the frame's name is unknown"
    unit = length_unit_of_file(path)
    u, how = frame_dimension_direction(path, item["name"], centre, axis, 0.5 * dia,
                                       unit[1] if unit else 1.0)
    drf = "|".join(d["name"] for d in item["datums"]) or "none"
    if u is None:
        return [], (f"a hole's axis positioned in two parallel planes: the semantic PMI gives "
                    "no zone direction across the axis (no zone orientation, no affected "
                    f"plane; the frame {drf} leaves two directions across the hole) and {how}")
    names = None
    if item["datums"]:
        names, r = _item_drf(item, ctx)
        if names is None:
            return [], r or "no datum reference frame"
    entry = {"name": ctx.name(f"{item['id']}_position"), "type": "position",
             "features": [[f"face:{f}" for f in g]], "tol": item["value"], "zone": "planes",
             "direction": [_mm(x) for x in u], "pmi": src}
    if names:
        entry["datums"] = names
    if item["material"]:
        size, r = _size_of(item, ctx, faces)
        if size is None:
            return [], r
        entry["material"], entry["size"] = item["material"], size
    src["zone_direction"] = how
    return [entry], ""
