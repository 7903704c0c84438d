"""The plan's ``datums`` entries of PMI datums set up from datum targets, and of common datums
(``E-F``), for :mod:`.pmi_plan` (the fits: :mod:`.datum_targets`, :mod:`.drf`).

* a datum of datum targets: ``{kind: targets, targets: [{type, at, face, direction, length,
  width}, ...]}`` from each target's placement as the file gives it
  (``XCAFDimTolObjects_DatumObject::GetDatumTargetAxis``, ``GetDatumTargetLength``/``Width``)
  and the face it is attached to;
* a common datum (two or more datums of the same precedence in a feature control frame,
  ``E-F``): one entry named ``E-F``: coplanar planes as one plane; cylinders as a pattern of
  their axes held at their CAD positions (coaxial ones: the common axis).
"""
from __future__ import annotations

_TYPES = {"Point": "point", "Line": "line", "Circle": "circle", "Rectangle": "rectangle"}


def targets_spec(d: dict, ctx, src: dict) -> tuple[dict | None, str]:
    """(the ``datums`` entry of a datum set up from datum targets, '') or (None, why not)."""
    out = []
    for t in d["targets"]:
        what = f"datum {d['name']}: target {d['name']}{t['number']} ({t['type']})"
        kind = _TYPES.get(t["type"])
        if kind is None:
            return None, f"{what} is of a type not set up yet (point, line, circle, rectangle)"
        if "at" not in t:
            return None, f"{what}: the file gives no position for it (no target parameters)"
        if len(t["faces"]) != 1:
            where = (f"{t['other'][0]}s" if t.get("other") else
                     f"{len(t['faces'])} faces" if t["faces"] else "no shape")
            return None, (f"{what} is attached to {where}, not to one face (the scan points "
                          "of a target are taken on its face)")
        face = ctx.fmap.get(t["faces"][0])
        if face is None:
            return None, f"{what}: its face could not be imported"
        e = {"type": kind, "at": [float(x) for x in t["at"]], "face": f"face:{face}"}
        if kind != "point":
            e["direction"] = [float(x) for x in t["direction"]]
            e["xdirection"] = [float(x) for x in t["xdirection"]]
            e["length"] = float(t["length"])
            if kind == "rectangle":
                e["width"] = float(t["width"])
            if not e["length"] > 0 or (kind == "rectangle" and not e["width"] > 0):
                return None, f"{what}: the file gives it no size"
        if kind in ("circle", "rectangle") and ctx.feats[face].kind != "plane":
            return None, f"{what} is an area on a {ctx.feats[face].kind} (areas on planes only)"
        out.append(e)
    areas = {e["type"] in ("circle", "rectangle") for e in out}
    if len(areas) > 1:
        return None, (f"datum {d['name']}: area targets mixed with point/line targets (not set "
                      "up yet)")
    return {"targets": out, "kind": "targets", "pmi": src}, ""


def common_datums(ds: list, ctx) -> tuple[list | None, str]:
    """(DRF names with each group of same-precedence datums joined as ``E-F``, '') or
    (None, why); registers the joined datum's entry in ``ctx.datum_specs``."""
    names = []
    for order in sorted({d["order"] for d in ds}):
        group = [d["name"] for d in ds if d["order"] == order]
        if len(group) == 1:
            names.append(group[0])
            continue
        joined = "-".join(group)
        missing = [n for n in group if n not in ctx.datum_specs]
        if missing:
            return None, ctx.datum_why.get(missing[0], f"datum {missing[0]} is not in the file")
        specs = [ctx.datum_specs[n] for n in group]
        if any("faces" not in s for s in specs):
            return None, (f"the common datum {joined} has a datum of datum targets (a common "
                          "datum of whole features only)")
        faces = [f for s in specs for f in s["faces"]]
        kinds = {s["kind"] for s in specs}
        if kinds == {"plane"}:
            from .pmi_plan import _planes_coplanar

            idx = [int(f.split(":")[1]) for f in faces]
            if not _planes_coplanar(ctx, idx):
                return None, f"the common datum {joined} is of planes that are not coplanar"
            kind = "plane"
        elif kinds <= {"axis", "pattern"}:
            kind = "pattern"
        else:
            return None, (f"the common datum {joined} joins {', '.join(sorted(kinds))} "
                          "datums (planes with planes or axes with axes only)")
        if joined not in ctx.datum_specs:
            ctx.datum_specs[joined] = {
                "faces": faces, "kind": kind,
                "pmi": {"kind": "datum", "type": "Datum", "id": f"DATUM_{joined}",
                        "name": joined}}
        names.append(joined)
    return names, ""


_MATERIAL = {"MaximumMaterialRequirement": "M", "LeastMaterialRequirement": "L"}


def datum_modifiers(item: dict, ctx) -> tuple[dict | None, str]:
    """({datum letter: 'M' | 'L'} of a tolerance's DRF, '') or (None, why not): each modified
    datum must be a single hole or boss axis with a toleranced diameter (``Size_Diameter``
    with limits on its faces), whose limits are then put into its ``datums`` entry
    (``size``: the MMB/LMB, :mod:`.datum_shift`)."""
    from .pmi_plan import _mm

    out = {}
    pmi_datums = {d["name"]: d for d in ctx.pmi["datums"]}
    for d in item["datums"]:
        if not d["modifiers"]:
            continue
        other = [m for m in d["modifiers"] if m not in _MATERIAL]
        mats = {_MATERIAL[m] for m in d["modifiers"] if m in _MATERIAL}
        if other or len(mats) != 1:
            return None, f"datum modifiers of {d['name']} ({', '.join(d['modifiers'])}) are not applied"
        spec = ctx.datum_specs.get(d["name"])
        if spec is None:
            return None, ctx.datum_why.get(d["name"], f"datum {d['name']} is not in the file")
        if spec.get("kind") != "axis":
            return None, (f"datum {d['name']} at {'MMB' if 'M' in mats else 'LMB'} is a "
                          f"{spec.get('kind')} datum; its shift is applied to one hole or "
                          "boss axis only")
        want = set(pmi_datums[d["name"]]["faces"])
        size = next((x for x in ctx.pmi["dimensions"] if x["type"] == "Size_Diameter"
                     and x["lower"] is not None and want and want <= set(x["faces"])), None)
        if size is None:
            return None, (f"datum {d['name']} at {'MMB' if 'M' in mats else 'LMB'}: no "
                          "toleranced diameter (Size_Diameter) on its faces for its boundary")
        spec["size"] = {"nominal": _mm(size["nominal"]), "lower": _mm(size["lower"]),
                        "upper": _mm(size["upper"])}
        out[d["name"]] = mats.pop()
    return out, ""
