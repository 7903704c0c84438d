"""An inspection plan from the semantic PMI of a STEP AP242 file (``shapeverify plan``).

:func:`plan_from_pmi` reads the PMI (:func:`shapeverify.cad.pmi.read_pmi`: datums, geometric
tolerances, dimensions, each with the faces it controls) and the model
(:func:`shapeverify.cad.load.load_model`), checks that both number the faces alike (the
vertices of every face the PMI names lie on the model's face of the same number), and maps
what the plan format can express:

=========================================  ===============================================
PMI                                        plan entry
=========================================  ===============================================
datum reference frame (plane, hole axis)   ``alignment: {type: datums, ...}`` (the DRF most
                                           tolerances use that the plan can build; a hole or
                                           boss datum is its cylinder face, fitted whole)
Flatness of one planar face                ``flatness`` (``feature: face:N``)
ProfileOfSurface without datums            ``surface_profile`` with ``datum: false``
ProfileOfSurface in the plan's DRF         ``surface_profile`` (``datum: true``)
Position (cylindrical zone, no material    ``hole`` ``position: {tol}``, one per hole of the
modifier) of holes, in the plan's DRF      tolerance (a pattern gives one entry per hole)
Size_Diameter with ± limits                ``hole`` ``diameter`` (a hole) or ``cylinder``
                                           ``diameter`` (a boss: ``faces`` when the CAD
                                           splits it); a drawn nominal that
                                           differs from the CAD's shifts the limits (the
                                           drawing's sizes, as deviations from the CAD)
Location_LinearDistance with ± limits      ``distance`` (:mod:`.pmi_dimensions`)
between two parallel planes (each side a
face or coplanar faces)
Location_Angular with ± limits between     ``angle``
two planes (each side a face or coplanar
faces)
Position without ⌀ on a slot's / tab's two ``position_zone`` ``zone: planes``
sides; with S⌀ on spheres                  (``zone: sphere``, one per sphere)
                                           (:mod:`.pmi_positions`)
Position without ⌀ of a hole's axis,       ``position`` ``zone: planes``, ``direction``
its frame drawn on a dimension line        (:mod:`.pmi_axis_planes`)
ProfileOfLine at a line drawn on a face    ``line_profile`` (:mod:`.pmi_profile_line`)
Size_Radius, Size_SphericalDiameter,       ``feature_size`` (:mod:`.pmi_sizes`)
Size_SphericalRadius with ± limits
Size_Angular of cones with ± limits;       ``cone_angle`` per cone; ``cone_diameter``
Size_Diameter on cone-plane circle edges   (a countersink at its surface, :mod:`.pmi_cones`)
Size_Thickness with ± limits on planar      ``distance`` between the two planes (a side of
faces in two parallel planes                several coplanar faces is one plane)
Parallelism/Perpendicularity/Angularity of  the orientation type with ``zone: median_plane``
a width's two opposite planar sides         (its derived median plane, :mod:`.median_plane`)
Straightness of a straight line drawn on a  ``straightness`` with ``through``, ``direction``,
face                                        ``length``: that line element of the face
Concentricity (⌀) of a cylinder to an axis  ``concentricity`` (:mod:`.concentricity`)
Symmetry of a width's two opposite sides     ``symmetry`` (:mod:`.symmetry`; the DRF holds
to a datum centre plane                      the centre plane the CAD centres it on)
Position (⌀) with datums at MMB / LMB       ``position`` with ``datum_modifiers`` (the best
                                            pose within the datum shift, :mod:`.datum_shift`)
Position (⌀) with a material modifier and   ``position`` with ``material``, ``size``,
a maximum ("MAX", ASME Y14.5-2009 §7.3.4)   ``max_tol`` (:mod:`shapeverify.cad.step_maxtol`)
Position (⌀) with a projected zone (Ⓟ,      ``position`` with ``projected`` (the length) and
§7.4.1) of holes                            ``projected_direction`` (the ``hole:k``'s axis: its
                                            open end; the PMI gives no side)
Orientation (⌀) with a projected zone of a  the orientation type, ``zone: diameter``, with
hole's axis                                 ``projected``, ``projected_direction`` (as above)
=========================================  ===============================================

Features the CAD splits into several faces (:mod:`.face_groups`): coaxial cylinder faces of
one radius are one cylinder (a boss's diameter, a datum axis, a position, a form tolerance
measure all of them together), coplanar faces with one outward side one plane.  A form or
orientation tolerance on several separate features (a "3X" cylindricity of three holes) gets
``features``, one list of faces per feature, each evaluated individually
(:mod:`.each_feature`).

The two segments of a composite feature control frame (``composite`` of the PMI reader,
:mod:`shapeverify.cad.step_composite`) keep ``composite: upper | lower`` on their entries; a
lower segment is always planned in its own datum frame (``position`` with ``datums``,
``surface_profile`` with ``datums``), where the evaluation lets the zone framework move
(:mod:`.composite`).

An item attached to an edge rather than a face (NIST CTC 02: a hole's rim circle) is mapped to
the feature the edge bounds by the PMI reader (:mod:`shapeverify.cad.pmi_edges`); its entry's
``pmi.attached`` says so.

A hole is named as ``shapeverify info --features`` names it (``hole:k``: the inner trim loop
on the cylinder's axis, with its diameter).  Every entry carries ``pmi: {kind, type, id, ...}``;
a PMI item that makes several entries (a pattern of holes) gives each the same ``id``.  Every
item the plan does not check is listed in ``unsupported`` with the reason, so each geometric
tolerance of the file appears exactly once: in ``characteristics`` or in ``unsupported``.

Not expressed yet (each such item says why in ``unsupported``): orientation, runout, form
other than flatness, location dimensions other than between two planes; positions with a material
modifier (no bonus tolerance); datum modifiers other than MMB/LMB of hole or boss axes, patterns
of them and common datums in a profile's DRF (:mod:`.pmi_datums`); datums on edges that bound
no cylinder; datum features left without faces (datums that the file ties to faces by an
``ITEM_IDENTIFIED_REPRESENTATION_USAGE`` that XCAF does not resolve, NIST CTC 01's B and C, are
attached by :mod:`shapeverify.cad.pmi_iiru`).  Area datum targets (rectangle, circle) that
the file attaches to no shape are put on the one planar face holding their placement
(:mod:`.pmi_datums`).  Line datum targets attached to an edge drawn
on a face take the edge's line; 'circular curve' targets (read from the STEP entities) are
``circular_line`` targets (:mod:`.pmi_datums`).
Datums set up from datum targets, patterns of cylinders and common datums (``E-F``) are in the
``datums`` table (:mod:`.pmi_datums`).
PMI on supplemental faces (open shells beside the solid, ``Model.supplemental``: never scanned)
is put on the solid faces each such face lies on, and the entry's ``pmi`` says so
(``from_supplemental: [280, 281]``, ``supplemental_note``); a supplemental face on no solid
face (a construction surface off the part) is left out of the item's faces, and an item left
with none is unsupported with that reason (:mod:`.pmi_supplemental`).

Example (needs the NIST test model)::

    >>> plan = plan_from_pmi("nist_ctc_01_asme1_ap242-e1.stp")      # doctest: +SKIP
    >>> [c.pmi.type for c in plan.characteristics]                   # doctest: +SKIP
    ['Flatness', 'Size_Diameter', ...]
"""
from __future__ import annotations

import logging
import re
from collections import Counter
from functools import cached_property
from pathlib import Path

import numpy as np
import yaml

from ..errors import CADImportError
from .features import _face_grid, model_features
from .plan import Plan, load_plan
from .pmi_supplemental import remap_supplemental

logger = logging.getLogger(__name__)

__all__ = ["plan_from_pmi", "pmi_plan", "plan_yaml", "PmiPlan"]

_HOLE_SIDE = "hole"
_BOSS_SIDE = "boss"


class PmiPlan:
    """A plan made from PMI and the rows of ``shapeverify info --pmi``.

    Attributes
    ----------
    plan : Plan          the validated plan
    data : dict          the plan as written (YAML-ready)
    rows : list of dict  one per PMI item: id, kind, type, value, limits, datums, faces,
                         features, entries (plan entry names) or reason (why unsupported)
    pmi : dict           what :func:`shapeverify.cad.pmi.read_pmi` read
    """

    def __init__(self, plan, data, rows, pmi):
        self.plan, self.data, self.rows, self.pmi = plan, data, rows, pmi

    def __repr__(self) -> str:
        return (f"PmiPlan({len(self.plan.characteristics)} characteristics, "
                f"{len(self.plan.unsupported)} unsupported, alignment "
                f"{self.plan.alignment.type!r})")


# ------------------------------------------------------------------------------ faces
def _face_map(pmi: dict, model) -> dict:
    """PMI face number (``TopExp_Explorer`` order) -> model face number, checked by geometry.

    The model leaves out faces it could not convert (``model.skipped_faces``: ``face i: ...``);
    the others keep their order.  Every vertex of every face the PMI names must lie within
    ``max(0.01 mm, 1e-5 x size)`` of that model face's boundary, or (a file whose trimming
    curves sit off its edges) within ``1e-3 x size`` and less than half as far from it as
    from any other face's."""
    n = int(pmi["n_faces"])
    skipped = set()
    for s in getattr(model, "skipped_faces", ()) or ():
        m = re.match(r"face (\d+):", s)
        if m:
            skipped.add(int(m.group(1)))
    kept = [i for i in range(n) if i not in skipped]
    if len(kept) != len(model.faces):
        raise CADImportError(
            f"{pmi['source']}: the PMI reader found {n} faces ({len(skipped)} skipped by the "
            f"import) but the model has {len(model.faces)}; the PMI cannot be tied to the "
            "model's face numbers")
    fmap = {e: k for k, e in enumerate(kept)}
    tol = max(0.01, 1e-5 * float(model.size))
    rims: dict = {}
    for e, verts in pmi["face_vertices"].items():
        e = int(e)
        if e not in fmap or not verts:
            continue
        V = np.asarray(verts, np.float64)
        d = _off_rim(V, _rim_of(model, fmap[e], rims))
        if d <= tol:
            continue
        # a file whose trimming curves sit off its edges (NIST CTC 05: three B-spline faces,
        # 0.24-0.36 mm) still matches when no other face's boundary is as near
        others = [(_off_rim(V, _rim_of(model, k, rims)), k) for k in range(len(model.faces))
                  if k != fmap[e]]
        best, k = min(others) if others else (np.inf, -1)
        if not (d < 0.5 * best and d <= max(1e-3 * float(model.size), 10 * tol)):
            raise CADImportError(
                f"{pmi['source']}: PMI face {e} does not match model face {fmap[e]} (a vertex "
                f"{d:.3g} mm off its boundary; model face {k}: {best:.3g} mm); the face "
                "numbering of the PMI reader and of the import differ")
        logger.info("%s: PMI face %d lies %.3g mm off model face %d's trimming loops (the "
                    "next face: %.3g mm); taken as that face", pmi["source"], e, d, fmap[e], best)
    return fmap


def _rim_of(model, k: int, cache: dict) -> np.ndarray:
    """Face k's trimming loops evaluated in 3D (cached in ``cache``)."""
    if k not in cache:
        face = model.faces[k]
        (u0, u1), (v0, v1) = face.surface.domain
        cache[k] = np.concatenate([face.evaluate(np.column_stack([
            np.clip(lp[:, 0], u0, u1), np.clip(lp[:, 1], v0, v1)])) for lp in face.loops])
    return cache[k]


def _off_rim(V, rim) -> float:
    """The largest distance of the points V from their nearest rim point."""
    from scipy.spatial import cKDTree

    return float(cKDTree(rim).query(V)[0].max())


def _side(model, i: int, c, a) -> str:
    """'hole' when face i's outward normal points at its cylinder's axis, else 'boss'."""
    X, N = _face_grid(model.faces[i])
    q = X - c
    radial = q - np.outer(q @ a, a)
    return _HOLE_SIDE if float(np.sum(N * radial)) < 0 else _BOSS_SIDE


def _cylinders(feats, model, faces) -> tuple[list, list]:
    """Coaxial groups of cylindrical faces of one radius (:func:`.face_groups.cylinder_groups`):
    ([(faces, centre, axis, diameter, side)], the faces that are not cylinders)."""
    from .face_groups import cylinder_groups

    cyl = [i for i in faces if feats[i].kind == "cylinder"]
    groups = []
    for g in cylinder_groups(feats, cyl, float(model.size)):
        f = feats[g[0]]
        groups.append([g, f.center, f.axis, float(f.diameter),
                       _side(model, g[0], f.center, f.axis)])
    return groups, [i for i in faces if feats[i].kind != "cylinder"]


def _hole_of(feats, group, size: float):
    """The ``hole:k`` feature on a cylinder group's axis with its diameter (lowest k), or None."""
    _, c, a, dia, _ = group
    for f in feats:
        if f.kind != "hole":
            continue
        q = f.center - c
        off = np.linalg.norm(q - (q @ a) * a)
        if (abs(f.diameter - dia) <= 1e-3 * dia + 1e-6
                and np.linalg.norm(np.cross(f.axis, a)) < 1e-3
                and off <= 1e-3 * dia + 1e-7 * size):
            return f
    return None


# ------------------------------------------------------------------------------ the mapping
def _mm(x: float) -> float:
    """A limit as the drawing writes it: rounded to 1e-9 mm (the reader's unit conversion
    leaves 0.20000000000000284), no negative zero."""
    return float(round(float(x), 9)) + 0.0


def _drawn_shift(item, cad: float) -> float | None:
    """How far a size's drawn nominal lies from the CAD's (0 within 1e-3 of it, rounding of
    the drawing's places), the plan's limits being deviations from the CAD size: a drawing
    whose nominal differs from the model's (FTC 08: 6.0452 drawn, 6.0325 modelled) keeps its
    own limits shifted by it -- None when the model lies outside them."""
    shift = float(item["nominal"]) - cad
    if abs(shift) <= 1e-3 * float(item["nominal"]) + 1e-6:
        return 0.0
    return shift if item["lower"] <= -shift <= item["upper"] else None

#: what the plan says of a statistical tolerance (ASME Y14.5-2009 2.16, the (ST) symbol)
STATISTICAL_NOTE = ("statistical tolerance (ST): the part is measured and judged against the "
                    "zone as an arithmetic limit; the drawing asks the process to hold it "
                    "statistically, which one part cannot show: see Cp/Cpk in the history")


def _src(item: dict) -> dict:
    out = {"kind": item["kind"], "type": item["type"], "id": item["id"]}
    for key in ("attached", "attached2"):       # faces found from the edges it points at
        if item.get(key):
            out[key] = item[key]
    if item.get("unit_note"):                   # values read in another unit than written
        out["unit_note"] = item["unit_note"]
    if item.get("from_supplemental"):           # faces outside the solid, mapped onto it
        out["from_supplemental"] = list(item["from_supplemental"])
        out["supplemental_note"] = item["supplemental_note"]
    if item["kind"] == "geometric_tolerance":
        out["value"] = item["value"]
        if item["value_type"] != "None":
            out["zone"] = item["value_type"]
        if item["datums"]:
            out["datums"] = "|".join(d["name"] for d in item["datums"])
        if item["material"]:
            out["material"] = item["material"]
        if item["modifiers"]:
            out["modifiers"] = list(item["modifiers"])
        if "Statistical_Tolerance" in item["modifiers"]:
            out["statistical_note"] = STATISTICAL_NOTE
        if item["zone_modifier"] != "None":
            out["zone_modifier"] = item["zone_modifier"]
        if item.get("composite"):
            out["composite"] = dict(item["composite"])
    elif item["kind"] == "dimension":
        out["nominal"] = item["nominal"]
        if item["lower"] is not None:
            out["lower"], out["upper"] = _mm(item["lower"]), _mm(item["upper"])
    else:
        out["name"] = item["name"]
    return out


def _drf_key(item) -> tuple:
    return tuple(d["name"] for d in item["datums"])


def _datum_faces(d: dict, ctx, targets_why: str) -> tuple[list | None, str]:
    """(the model's face numbers of a PMI datum, '') or (None, why not): a datum set up from
    datum targets (``targets_why`` says what the caller lacks for them), on no face, or on a
    face that was not imported."""
    if d["type"] == "DatumTarget" or d["targets"]:
        return None, (f"datum {d['name']} is set up from datum targets "
                      f"({', '.join(t['type'] for t in d['targets'])}); {targets_why}")
    if not d["faces"] and d.get("supplemental_reason"):
        return None, f"datum {d['name']}: {d['supplemental_reason']}"
    if not d["faces"]:
        if d["other"]:
            return None, f"datum {d['name']} is attached to {d['other'][0]}s, not faces"
        return None, (f"datum {d['name']} is not attached to any face in the file (as "
                      "OpenCASCADE's XCAF reader reads it)"
                      + (f": {d['unattached']}" if d.get("unattached") else ""))
    faces = [ctx.fmap.get(f) for f in d["faces"]]
    if any(f is None for f in faces):
        return None, f"a face of datum {d['name']} could not be imported"
    return faces, ""


def _datum_ref(d: dict, ctx) -> tuple[str | None, str]:
    """(plan feature ref, '') of a datum, or (None, why not)."""
    faces, why = _datum_faces(d, ctx, "the plan's datum alignment takes whole datum features")
    if faces is None:
        return None, why
    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    if not groups and len(other) == 1 and ctx.feats[other[0]].kind == "plane":
        return f"face:{other[0]}", ""
    if len(groups) == 1 and not other and len(groups[0][0]) == 1:
        # the datum feature is the hole's (or boss's) cylindrical surface: its axis is fitted
        # on all of it (:mod:`.datums`), not on the rim of one end (a rim of 20 scan points at
        # 1 mm spacing puts the axis 0.2 mm off and lets the frame fail as a bad fit)
        return f"face:{groups[0][0][0]}", ""
    if len(groups) == 1 and not other and groups[0][4] == _HOLE_SIDE:
        h = _hole_of(ctx.feats, groups[0], ctx.size)
        if h is not None:
            return h.id, ""
        return None, f"datum {d['name']}: no hole of `info --features` on its axis"
    kinds = sorted({ctx.feats[f].kind for f in faces})
    return None, (f"datum {d['name']} is a feature of {len(faces)} faces ({', '.join(kinds)}); "
                  "the plan's datums are one plane face or one hole")


def _planes_coplanar(ctx, faces) -> bool:
    """The planar faces lie in one plane with one outward side (:mod:`.face_groups`)."""
    from .face_groups import same_plane

    f0 = ctx.feats[faces[0]]
    return all(same_plane(ctx.feats[f], f0, ctx.size) for f in faces)


def _datum_spec(d: dict, ctx) -> tuple[dict | None, str]:
    """(the plan's ``datums`` entry of a PMI datum, '') or (None, why not) (:mod:`.drf`)."""
    if d["targets"] and not d["faces"]:
        from .pmi_datums import targets_spec

        return targets_spec(d, ctx, _src(d))
    faces, why = _datum_faces(d, ctx, "the target positions are not read from the file")
    if faces is None:
        return None, why
    src = _src(d)
    kinds = {ctx.feats[f].kind for f in faces}
    if kinds == {"plane"} and _planes_coplanar(ctx, faces):
        return {"faces": [f"face:{f}" for f in faces], "kind": "plane", "pmi": src}, ""
    if kinds == {"cylinder"}:
        groups, _ = _cylinders(ctx.feats, ctx.model, faces)
        if len(groups) == 1:
            return {"faces": [f"face:{f}" for f in faces], "kind": "axis", "pmi": src}, ""
        return {"faces": [f"face:{f}" for f in faces], "kind": "pattern", "pmi": src}, ""
    if kinds == {"plane"}:
        f0 = ctx.feats[faces[0]]
        one = [f for f in faces if ctx.feats[f].axis @ f0.axis > 0]
        two = [f for f in faces if ctx.feats[f].axis @ f0.axis < 0]
        if one and two and _planes_coplanar(ctx, one) and _planes_coplanar(ctx, two) and \
                abs(ctx.feats[two[0]].axis @ f0.axis + 1) < 1e-6:
            return {"faces": [f"face:{f}" for f in faces], "kind": "midplane", "pmi": src}, ""
        return None, (f"datum {d['name']} is {len(faces)} planar faces that are neither one "
                      "plane nor the two sides of a width")
    return None, (f"datum {d['name']} is a feature of {len(faces)} faces "
                  f"({', '.join(sorted(kinds))}); datum features are planes or axes")


def _item_drf(item, ctx, shift_ok: bool = False) -> tuple[list | None, str]:
    """(datum letters of the item's DRF, '') when every datum can be fitted, else (None, why).
    ``shift_ok``: the caller applies MMB/LMB datum modifiers (:mod:`.pmi_datums`; they are
    in ``ctx.last_modifiers``)."""
    ds = item["datums"]
    ctx.last_modifiers = {}
    mods = [f"{d['name']} {', '.join(d['modifiers'])}" for d in ds if d["modifiers"]]
    if mods and not shift_ok:
        return None, f"datum modifiers ({'; '.join(mods)}) are not applied"
    orders = [d["order"] for d in ds]
    if len(set(orders)) != len(orders):
        from .pmi_datums import common_datums

        names, why = common_datums(ds, ctx)
        if names is None:
            return None, why
    else:
        names = [d["name"] for d in sorted(ds, key=lambda d: d["order"])]
    for n in names:
        if n not in ctx.datum_specs:
            return None, ctx.datum_why.get(n, f"datum {n} is not in the file")
    if mods:
        from .pmi_datums import datum_modifiers

        dm, why = datum_modifiers(item, ctx, names)
        if dm is None:
            return None, why
        ctx.last_modifiers = dm
    for n in names:
        ctx.used_datums.add(n)
    return names, ""


class _Ctx:
    def __init__(self, pmi, model, fmap):
        self.pmi, self.model, self.fmap = pmi, model, fmap
        self.size = float(model.size)
        self.names: Counter = Counter()
        self.datum_specs: dict = {}
        self.datum_why: dict = {}
        self.used_datums: set = set()
        #: the {DRF datum: 'M' | 'L'} of the last :func:`_item_drf` with ``shift_ok``
        self.last_modifiers: dict = {}

    @cached_property
    def feats(self) -> list:
        """The model's features, found when a PMI item first needs them (a file with no
        semantic PMI needs none: NIST FTC 08's AP203 edition spent 63 s of 92 on them)."""
        return model_features(self.model)

    def name(self, base: str) -> str:
        self.names[base] += 1
        return base if self.names[base] == 1 else f"{base}_{self.names[base]}"


def _alignment(ctx, datums: dict):
    """(alignment dict, DRF key or None, {datum name: why it is not usable})."""
    why = {}
    refs = {}
    for name, d in datums.items():
        ref, reason = _datum_ref(d, ctx)
        if ref is None:
            why[name] = reason
        else:
            refs[name] = ref
    use = Counter(_drf_key(t) for t in ctx.pmi["tolerances"] if t["datums"])
    for key, _ in sorted(use.items(), key=lambda kv: (-kv[1], kv[0])):
        if len(key) < 2 or len(set(key)) != len(key) or any(k not in refs for k in key):
            continue
        r0 = refs[key[0]]
        if not r0.startswith("face:") or ctx.feats[int(r0[5:])].kind != "plane":
            continue          # the alignment's primary datum is a plane
        al = {"type": "datums", "primary": refs[key[0]], "secondary": refs[key[1]]}
        if len(key) > 2:
            al["tertiary"] = refs[key[2]]
        if len(key) > 3:
            continue
        al["pmi"] = [_src(datums[k]) for k in key]
        return al, key, why
    return {"type": "best_fit", "faces": "all"}, None, why


def _faces_ok(item, ctx, key="faces"):
    faces = [ctx.fmap.get(f) for f in item[key]]
    if any(f is None for f in faces):
        return None, "a face it names could not be imported (see the import's warnings)"
    if not faces and item.get("supplemental_reason"):
        return None, item["supplemental_reason"]
    if not faces:
        if item.get("edge_reason"):
            return None, item["edge_reason"]
        what = f"{item['other'][0]}s" if item.get("other") else "no shape"
        return None, f"it is attached to {what}, not to faces"
    return faces, ""


def unapplied_modifiers(item: dict) -> str:
    """Why an item is unsupported when it carries modifiers the plan does not apply (any but
    :data:`_ANY_TYPE`, or a material modifier), or '' when it carries none."""
    extra = [m for m in item["modifiers"] if m not in _ANY_TYPE] + \
        ([f"material {item['material']}"] if item["material"] else [])
    return f"modifiers {', '.join(extra)} are not applied by the plan" if extra else ""


#: tolerance modifiers that change what no characteristic measures: Free_State (a scan of the
#: unrestrained part is a free-state measurement) and Statistical_Tolerance (the zone is the
#: same; conformance is judged over the process, :data:`STATISTICAL_NOTE`)
_ANY_TYPE = {"Free_State", "Statistical_Tolerance"}
#: and those that do not for one type
_HARMLESS = {"ProfileOfSurface": {"All_Around", "All_Over"}, "Flatness": set(), "Position": set(),
             "Parallelism": {"Tangent_Plane"}, "Perpendicularity": {"Tangent_Plane"},
             "Angularity": {"Tangent_Plane"}}


def _plain_zone_reason(item, note: str = "") -> str:
    """'' or why a tolerance's zone is not the plain one the plan measures: a zone modifier
    (``note`` appended), or a modifier other than :data:`_ANY_TYPE`."""
    if item["zone_modifier"] != "None":
        return f"a {item['zone_modifier']} zone modifier{note}"
    extra = [m for m in item["modifiers"] if m not in _ANY_TYPE]
    return f"modifier {', '.join(extra)} is not applied by the plan" if extra else ""


def _modifier_reason(item) -> str:
    if item["type"] not in _HARMLESS:
        return ""
    extra = [m for m in item["modifiers"] if m not in _HARMLESS[item["type"]] | _ANY_TYPE]
    return f"modifier {', '.join(extra)} is not applied by the plan" if extra else ""


def _drf_reason(item, drf, why) -> str:
    key = _drf_key(item)
    if not key:
        return ""
    mods = [f"{d['name']} {', '.join(d['modifiers'])}" for d in item["datums"] if d["modifiers"]]
    if key == drf and mods:
        return f"datum modifiers ({'; '.join(mods)}) are not applied by the plan's alignment"
    if key == drf:
        return ""
    missing = [why[k] for k in key if k in why]
    base = (f"its datum reference frame {'|'.join(key)} is not the plan's alignment "
            f"({'|'.join(drf) if drf else 'best fit: no datum reference frame of the file can be built'})")
    return base + (f"; {missing[0]}" if missing else "")


def _tolerance(item, ctx, drf, why) -> tuple[list, str]:
    """(plan characteristics, '') or ([], reason); the segments of a composite frame carry
    ``composite: upper | lower`` (:mod:`.composite`)."""
    entries, reason = _tolerance_entries(item, ctx, drf, why)
    seg = (item.get("composite") or {}).get("segment")
    if seg and entries:
        if {e["type"] for e in entries} - {"position", "surface_profile"}:
            return [], (f"the {seg} segment of a composite frame on features the plan "
                        "checks as " + ", ".join(sorted({e['type'] for e in entries})) +
                        " (composite segments are planned for position and surface_profile)")
        for e in entries:
            e["composite"] = seg
    return entries, reason


def _lower(item) -> bool:
    return (item.get("composite") or {}).get("segment") == "lower"


def _tolerance_entries(item, ctx, drf, why) -> tuple[list, str]:
    t = item["type"]
    value = item.get("value")
    mat = item.get("material")
    zero_ok = t == "Position" and mat in ("M", "L")   # 0 at MMC/LMC: all of it bonus
    if value is not None and not value > 0 and not (value == 0 and zero_ok):
        return [], (f"a tolerance of {value:g}"
                    + (f" with material modifier {mat}" if mat and mat != "None" else "")
                    + ": a zone of 0 is planned only for a position at MMC or LMC (all of "
                    "it bonus)")
    if t == "ProfileOfLine":
        from .pmi_profile_line import line_profile_entries

        return line_profile_entries(item, ctx, drf, why, _src(item))
    if t == "Straightness" and not item["faces"] and item.get("edges"):
        return _straightness_of_line(item, ctx, _src(item))
    faces, reason = _faces_ok(item, ctx)
    if faces is None:
        return [], reason
    src = _src(item)
    reason = _modifier_reason(item)
    if reason and "All_Around" in item["modifiers"]:
        from .pmi_all_around import all_around_reason

        reason = all_around_reason(item, ctx, faces, reason)
    if reason:
        return [], reason
    if t == "Flatness":
        if len(faces) > 1 and {ctx.feats[f].kind for f in faces} == {"plane"} and \
                _planes_coplanar(ctx, faces):
            return [{"name": ctx.name(f"{item['id']}_flatness"), "type": "flatness",
                     "faces": [f"face:{f}" for f in faces], "tol": item["value"],
                     "pmi": src}], ""
        if len(faces) != 1 or ctx.feats[faces[0]].kind != "plane":
            return [], (f"flatness of {len(faces)} faces ({ctx.feats[faces[0]].kind}) that are "
                        "not one plane")
        return [{"name": ctx.name(f"{item['id']}_flatness"), "type": "flatness",
                 "feature": f"face:{faces[0]}", "tol": item["value"], "pmi": src}], ""
    if t == "ProfileOfSurface":
        if item["zone_modifier"] != "None":
            return [], f"a {item['zone_modifier']} zone modifier (uniform zones only)"
        if item["datums"]:
            r = _drf_reason(item, drf, why) or _lower(item)
            if r:            # not the plan's alignment, or a lower segment: its own DRF
                names, r2 = _item_drf(item, ctx, shift_ok=True)
                if names is None:
                    return [], r2
                entry = {"name": ctx.name(f"{item['id']}_profile"), "type": "surface_profile",
                         "faces": [f"face:{f}" for f in faces], "tol": item["value"],
                         "datums": names, "pmi": src}
                dm = dict(ctx.last_modifiers)
                if dm:
                    entry["datum_modifiers"] = dm
                return [entry], ""
        return [{"name": ctx.name(f"{item['id']}_profile"), "type": "surface_profile",
                 "faces": [f"face:{f}" for f in faces], "tol": item["value"],
                 "datum": bool(item["datums"]), "pmi": src}], ""
    if t in ("Parallelism", "Perpendicularity", "Angularity"):
        return _orientation(item, ctx, faces, src)
    if t == "Position":
        if item["value_type"] in ("None", "SphericalDiameter"):
            from .pmi_positions import position_zone_entries

            return position_zone_entries(item, ctx, faces, src)
        if item["material"] or (item["value_type"] == "Diameter"
                                and item["zone_modifier"] == "Projected") or (
                item["value_type"] == "Diameter" and item["zone_modifier"] == "None"
                and (_drf_reason(item, drf, why) or _lower(item))):
            return _position(item, ctx, faces, src)
        if item["value_type"] != "Diameter":
            zone = {"None": "two parallel planes", "SphericalDiameter": "a sphere"}.get(
                item["value_type"], item["value_type"])
            return [], (f"the zone is {zone} (no \u2300); the plan's position is a cylindrical "
                        "zone of a hole's axis")
        if item["zone_modifier"] != "None":
            return [], f"a {item['zone_modifier']} zone modifier"
        r = _drf_reason(item, drf, why)
        if r:
            return [], r
        groups, other = _cylinders(ctx.feats, ctx.model, faces)
        if other or not groups:
            return [], "it controls faces that are not cylinders (the plan's position is of holes)"
        out = []
        for g in groups:
            if g[4] != _HOLE_SIDE:
                return [], "position of a boss (the plan's position is of holes)"
            h = _hole_of(ctx.feats, g, ctx.size)
            if h is None:
                return [], (f"no hole of `info --features` on the axis of face:{g[0][0]} (a "
                            "hole whose rim is not an inner loop of one face)")
            out.append({"name": ctx.name(f"{item['id']}_position_{h.id.replace(':', '')}"),
                        "type": "hole", "feature": h.id, "position": {"tol": item["value"]},
                        "pmi": src})
        return out, ""
    if t in _FORMS or t in _RUNOUTS:
        return _form_or_runout(item, ctx, faces, src)
    if t == "Concentricity":
        return _concentricity(item, ctx, faces, src)
    if t == "Symmetry":
        from .pmi_symmetry import symmetry_entries

        return symmetry_entries(item, ctx, faces, src)
    return [], f"no plan characteristic for {t} yet (issue 28 item 3)"


#: PMI form tolerances -> plan types, and the face kinds each applies to
_FORMS = {"CircularityOrRoundness": ("circularity", {"cylinder"}),
          "Cylindricity": ("cylindricity", {"cylinder"}),
          "Straightness": ("straightness", {"cylinder", "plane"})}
#: PMI runout tolerances -> plan types
_RUNOUTS = {"CircularRunout": "circular_runout", "TotalRunout": "total_runout"}


def _form_or_runout(item, ctx, faces, src) -> tuple[list, str]:
    """Circularity, cylindricity, straightness (a cylinder's axis with ⌀, a plane's line
    elements without) and circular / total runout about the item's datum axis."""
    t = item["type"]
    if item["zone_modifier"] != "None":
        return [], f"a {item['zone_modifier']} zone modifier"
    why = unapplied_modifiers(item)
    if why:
        return [], why
    kinds = {ctx.feats[f].kind for f in faces}
    kind, allowed = _FORMS.get(t, (_RUNOUTS.get(t), None))
    entry = {"name": ctx.name(f"{item['id']}_{kind}"), "type": kind,
             "faces": [f"face:{f}" for f in faces], "tol": item["value"], "pmi": src}
    if t in _RUNOUTS:
        if not item["datums"]:
            return [], "a runout without a datum axis"
        names, r = _item_drf(item, ctx)
        if names is None:
            return [], r or "no datum reference frame"
        return [{**entry, "datums": names}], ""
    if item["datums"]:
        return [], f"a form tolerance ({t}) with datums {_drf_key(item)}"
    if not kinds <= allowed or len(kinds) != 1:
        return [], f"{t} of {sorted(kinds)} faces (the plan's {kind} takes {sorted(allowed)})"
    feats = _features(ctx, faces)
    if len(feats) > 1:
        # separate features under one frame (a "3X" cylindricity of three pins): each
        # individually (:mod:`.each_feature`); one cylinder the CAD splits stays one feature
        entry["features"] = feats
    if kind == "straightness":
        zone = "diameter" if item["value_type"] == "Diameter" else "lines"
        if (zone == "diameter") != (kinds == {"cylinder"}):
            return [], (f"straightness of a {kinds.pop()} with a "
                        f"{'⌀' if zone == 'diameter' else 'two-line'} zone")
        entry["zone"] = zone
    return [entry], ""


def _features(ctx, faces) -> list:
    """The separate features (cylinders, planes: :func:`.face_groups.features_of`) of an
    item's faces, as the plan's face lists."""
    from .face_groups import features_of

    groups, _ = features_of(ctx.feats, faces, ctx.size)
    return [[f"face:{f}" for f in g] for _, g in groups]


def _straightness_of_line(item, ctx, src) -> tuple[list, str]:
    """Straightness of a straight line drawn on one face (NIST CTC 05 GT6: a generator of a
    cylinder): the line element of that face along the line, over the line's length
    (:func:`.gdt._straightness_of_line`)."""
    recs = item["edges"]
    if len(recs) != 1 or recs[0]["curve"] != "Line" or len(recs[0].get("on_faces") or []) != 1:
        return [], item.get("edge_reason") or "straightness of edges that are not one line drawn on one face"
    if item["zone_modifier"] != "None" or item["value_type"] != "None" or item["datums"]:
        return [], (f"straightness of a line with a {item['value_type']} zone, zone modifier "
                    f"{item['zone_modifier']} or datums")
    why = unapplied_modifiers(item)
    if why:
        return [], why
    face = ctx.fmap.get(recs[0]["on_faces"][0])
    if face is None:
        return [], "its face could not be imported"
    P = np.asarray(recs[0]["points"], float)
    a, b = P[0], P[-1]
    L = float(np.linalg.norm(b - a))
    if not L > 0:
        return [], "its line has no length"
    u = (b - a) / L
    return [{"name": ctx.name(f"{item['id']}_straightness"), "type": "straightness",
             "faces": [f"face:{face}"], "tol": item["value"], "zone": "lines",
             "direction": [float(x) + 0.0 for x in u],
             "through": [float(x) + 0.0 for x in 0.5 * (a + b)], "length": L,
             "pmi": {**src, "attached": f"a line drawn on face {face}: its line element"}}], ""


def _concentricity(item, ctx, faces, src) -> tuple[list, str]:
    """Concentricity (⌀ zone) of one surface of revolution (a cylinder) about an axis datum
    (:mod:`.concentricity`)."""
    if item["value_type"] != "Diameter" or item["zone_modifier"] != "None":
        return [], "a concentricity without a ⌀ zone, or with a zone modifier"
    why = unapplied_modifiers(item)
    if why:
        return [], why
    if not item["datums"]:
        return [], "a concentricity without a datum axis"
    kinds = {ctx.feats[f].kind for f in faces}
    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    if kinds != {"cylinder"} or len(groups) != 1:
        return [], (f"concentricity of {len(faces)} faces ({', '.join(sorted(kinds))}) that "
                    "are not one cylinder")
    names, r = _item_drf(item, ctx)
    if names is None:
        return [], r or "no datum reference frame"
    if not any(ctx.datum_specs[n].get("kind") == "axis" for n in names):
        return [], f"its datum reference frame {'|'.join(names)} has no axis datum"
    return [{"name": ctx.name(f"{item['id']}_concentricity"), "type": "concentricity",
             "faces": [f"face:{f}" for f in faces], "tol": item["value"], "datums": names,
             "pmi": src}], ""


def _size_of(item, ctx, faces) -> tuple[dict | None, str]:
    """The ``size`` limits of a material modifier: the Size_Diameter dimension on the same
    faces (the drawing's nominal and limits)."""
    want = set(item["faces"])
    for d in ctx.pmi["dimensions"]:
        if d["type"] == "Size_Diameter" and d["lower"] is not None and want <= set(d["faces"]):
            return {"lower": _mm(d["lower"]), "upper": _mm(d["upper"]),
                    "nominal": _mm(d["nominal"])}, ""
    return None, (f"material modifier {item['material']}: no toleranced diameter (Size_Diameter) "
                  "on its faces for the bonus tolerance")


def _orientation(item, ctx, faces, src) -> tuple[list, str]:
    t = item["type"]
    projected = item["zone_modifier"] == "Projected" and item["value_type"] == "Diameter"
    if item["zone_modifier"] != "None" and not projected:
        return [], f"a {item['zone_modifier']} zone modifier"
    if projected and not item["zone_modifier_value"] > 0:
        return [], "a Projected zone modifier without its length"
    names, r = _item_drf(item, ctx)
    if names is None:
        return [], r or "no datum reference frame"
    kinds = {ctx.feats[f].kind for f in faces}
    entry = {"name": ctx.name(f"{item['id']}_{t.lower()}"), "type": t.lower(),
             "faces": [f"face:{f}" for f in faces], "tol": item["value"], "datums": names,
             "pmi": src}
    if kinds == {"plane"} and item["value_type"] == "None" and not projected:
        if not _planes_coplanar(ctx, faces):
            f0 = ctx.feats[faces[0]]
            one = [f for f in faces if ctx.feats[f].axis @ f0.axis > 0]
            two = [f for f in faces if ctx.feats[f].axis @ f0.axis < 0]
            if one and two and _planes_coplanar(ctx, one) and _planes_coplanar(ctx, two) and \
                    abs(ctx.feats[two[0]].axis @ f0.axis + 1) < 1e-6:
                # a width (a feature of size): the zone holds its derived median plane
                extra = ([f"material {item['material']}"] if item["material"] else []) + \
                    [m for m in item["modifiers"] if m not in _ANY_TYPE]
                if extra:
                    return [], (f"{t.lower()} of a width's median plane with "
                                f"{', '.join(extra)} (not applied)")
                entry["zone"] = "median_plane"
                return [entry], ""
            # several separate planes under one frame: each individually (:mod:`.each_feature`)
            entry["features"] = _features(ctx, faces)
        if item["material"]:
            return [], f"material modifier {item['material']} on a plane"
        entry["zone"] = "planes"
        if "Tangent_Plane" in item["modifiers"]:
            entry["tangent_plane"] = True
        return [entry], ""
    if kinds == {"cylinder"} and item["value_type"] == "Diameter":
        groups, _ = _cylinders(ctx.feats, ctx.model, faces)
        if len(groups) > 1:       # several axes under one frame: each individually
            entry["features"] = [[f"face:{f}" for f in g[0]] for g in groups]
        if "Tangent_Plane" in item["modifiers"]:
            return [], "a tangent plane modifier on an axis"
        entry["zone"] = "diameter"
        if projected:          # the axis extended out of the hole's mouth (§7.4.1)
            r = _projected(item, ctx, groups, entry, src)
            if r:
                return [], r
        if item["material"]:
            size, r = _size_of(item, ctx, faces)
            if size is None:
                return [], r
            entry["material"], entry["size"] = item["material"], size
        return [entry], ""
    zone = "\u2300 (an axis)" if item["value_type"] == "Diameter" else "two parallel planes"
    return [], (f"{t.lower()} of {', '.join(sorted(kinds))} faces with a {zone} zone (planes "
                "with a planes zone, cylinders with a \u2300 zone are supported)")


def _counterbore_axes(ctx, groups, other) -> list | None:
    """The counterbored holes of a position's faces: [[hole group, counterbore group], ...]
    (groups of :func:`_cylinders`, smaller diameter first) when the cylinders pair up coaxially
    (two diameters per axis) and the other faces are one plane per axis square to it (the
    counterbores' floors), else None."""
    if not groups or not other or {ctx.feats[f].kind for f in other} != {"plane"}:
        return None
    axes: list = []
    for g in groups:
        for a in axes:
            q = g[1] - a[0][1]
            if np.linalg.norm(np.cross(g[2], a[0][2])) < 1e-6 and \
                    np.linalg.norm(q - (q @ g[2]) * g[2]) <= 1e-6 * ctx.size:
                a.append(g)
                break
        else:
            axes.append([g])
    if any(len(a) != 2 or a[0][3] == a[1][3] for a in axes) or len(other) != len(axes):
        return None
    for f in other:         # each floor square to an axis
        n = np.asarray(ctx.feats[f].axis, float)
        if not any(abs(abs(float(n @ a[0][2])) - 1.0) < 1e-6 for a in axes):
            return None
    return [sorted(a, key=lambda g: g[3]) for a in axes]


def _group_sizes(item, ctx, groups) -> tuple[list | None, str]:
    """The size limits of each cylinder group of a material-modified tolerance whose features
    are not all one size (a counterbored hole: hole and counterbore): the Size_Diameter with
    limits on faces of this tolerance that all lie on cylinders of the group's CAD diameter
    (a "4X" size the file attaches to one instance applies to every instance of that diameter
    under the frame)."""
    mine = {ctx.fmap.get(f): f for f in item["faces"]}
    out = []
    for g in groups:
        got = None
        for d in ctx.pmi["dimensions"]:
            if d["type"] != "Size_Diameter" or d["lower"] is None or not d["faces"]:
                continue
            fs = [ctx.fmap.get(f) for f in d["faces"]]
            if any(f is None or f not in mine for f in fs):
                continue
            if all(ctx.feats[f].kind == "cylinder"
                   and abs(float(ctx.feats[f].diameter) - g[3]) <= 1e-6 * ctx.size for f in fs):
                got = {"lower": _mm(d["lower"]), "upper": _mm(d["upper"]),
                       "nominal": _mm(d["nominal"])}
                break
        if got is None:
            return None, (f"material modifier {item['material']}: no toleranced diameter "
                          f"(Size_Diameter) on its \u2300{g[3]:g} faces (face:{g[0][0]}) for "
                          "their bonus tolerance")
        out.append(got)
    return out, ""


def _projected(item, ctx, groups, entry, src) -> str:
    """Put a Projected zone's ``projected`` (length) and ``projected_direction`` into
    ``entry`` (and the frame's Ⓟ length into ``src``); '' or why it cannot be planned."""
    # the side of the projection: the mating part's, the hole's entry face (where the
    # frame's arrow points); the PMI does not give it: the hole's open end
    dirs = []
    for g in groups:
        h = _hole_of(ctx.feats, g, ctx.size) if g[4] == _HOLE_SIDE else None
        if h is None:
            return (f"a Projected zone modifier on face:{g[0][0]}, not a hole's wall "
                    "with a mouth of `info --features` (the side the zone goes)")
        dirs.append(np.asarray(h.axis, float))
    if any(float(d @ dirs[0]) < 1.0 - 1e-9 for d in dirs):
        return ("a Projected zone modifier on holes that open on different sides "
                "(one projected_direction per entry)")
    entry["projected"] = _mm(item["zone_modifier_value"])
    entry["projected_direction"] = [_mm(x) for x in dirs[0]]
    src["zone_modifier_value"] = _mm(item["zone_modifier_value"])   # the frame's Ⓟ length
    src["projected_side"] = "the holes' open end (the PMI gives no side)"
    return ""


def _position(item, ctx, faces, src) -> tuple[list, str]:
    if item["value_type"] != "Diameter":
        zone = {"None": "two parallel planes", "SphericalDiameter": "a sphere"}.get(
            item["value_type"], item["value_type"])
        return [], f"the zone is {zone} (no \u2300); position is of axes in a cylindrical zone"
    if item["zone_modifier"] not in ("None", "Projected"):
        return [], f"a {item['zone_modifier']} zone modifier"
    if item["zone_modifier"] == "Projected" and not item["zone_modifier_value"] > 0:
        return [], "a Projected zone modifier without its length"
    names, dm = None, {}
    if item["datums"] or not _lower(item):   # a lower segment without datums floats
        names, r = _item_drf(item, ctx, shift_ok=True)
        if names is None:
            return [], r or "no datum reference frame"
        dm = dict(ctx.last_modifiers)
    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    cbores = _counterbore_axes(ctx, groups, other)
    if (other and cbores is None) or not groups:
        return [], "it controls faces that are not cylinders (position is of axes)"
    if cbores:
        # one frame under a counterbored hole's callout: the hole's and the counterbore's
        # axes each lie in the zone about their common true position, each with the bonus of
        # its own size (ASME Y14.5-2009, positional tolerancing of coaxial features: the
        # counterbored holes under one callout share the hole's frame); the
        # floors (the counterbores' depth) are no axes and are not positioned
        src["counterbored_holes"] = (
            f"{len(cbores)} counterbored holes: the \u2300{cbores[0][0][3]:g} hole and the "
            f"\u2300{cbores[0][1][3]:g} counterbore of each, coaxial, each its own axis in the "
            "zone at their common true position with its own size's bonus; the floors "
            f"({', '.join(f'face:{f}' for f in other)}) are not positioned")
        groups = [g for a in cbores for g in a]
    entry = {"name": ctx.name(f"{item['id']}_position"), "type": "position",
             "features": [[f"face:{f}" for f in g[0]] for g in groups], "tol": item["value"],
             "pmi": src}
    if names:
        entry["datums"] = names
    if dm:
        entry["datum_modifiers"] = dm
    if item["zone_modifier"] == "Projected":
        r = _projected(item, ctx, groups, entry, src)
        if r:
            return [], r
    if item["material"] and len({round(g[3], 9) for g in groups}) > 1:
        sizes, r = _group_sizes(item, ctx, groups)
        if sizes is None:
            return [], r
        entry["material"], entry["feature_sizes"] = item["material"], sizes
    elif item["material"]:
        size, r = _size_of(item, ctx, faces)
        if size is None:
            return [], r
        entry["material"], entry["size"] = item["material"], size
    if item["material"]:
        if item.get("max_value", 0.0) > 0.0:     # the frame's "MAX" (ASME Y14.5-2009 §7.3.4)
            entry["max_tol"] = _mm(item["max_value"])
            src["max_value"] = entry["max_tol"]
    return [entry], ""


def _dimension(item, ctx) -> tuple[list, str]:
    t = item["type"]
    if t in ("Location_LinearDistance", "Location_Angular"):
        from .pmi_dimensions import between_entries

        return between_entries(item, ctx, _src(item), ctx.name)
    if t == "Size_Thickness":
        from .pmi_dimensions import thickness_entries

        return thickness_entries(item, ctx, _src(item), ctx.name)
    if t in ("Size_Radius", "Size_SphericalDiameter", "Size_SphericalRadius", "Size_Angular"):
        from .pmi_cones import angular_entries
        from .pmi_sizes import size_entries

        return (angular_entries if t == "Size_Angular" else size_entries)(item, ctx, _src(item))
    if t != "Size_Diameter":
        if t == "Location_None":
            from .pmi_sizes import LOCATION_NONE_REASON

            return [], LOCATION_NONE_REASON
        if t in ("DimensionPresentation", "CommonLabel"):
            return [], f"{t}: a presentation without a semantic value"
        return [], f"no plan characteristic for the dimension {t} yet (issue 28 item 3)"
    if item["lower"] is None or not item["lower"] < item["upper"]:
        return [], "a diameter without \u00b1 limits (a basic or reference dimension)"
    if item["modifiers"]:
        return [], f"size modifiers {', '.join(item['modifiers'])}"
    faces, reason = _faces_ok(item, ctx)
    if faces is None:       # a countersink's diameter at its edges, else the reason
        from .pmi_cones import countersink_entries
        return countersink_entries(item, ctx, _src(item), reason)
    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    if other or not groups:
        return [], "it controls faces that are not cylinders"
    out = []
    for g in groups:
        shift = _drawn_shift(item, g[3])
        if shift is None:
            return [], (f"the nominal \u2300{item['nominal']:g} differs from the CAD cylinder's "
                        f"\u2300{g[3]:.4f} by more than its limits")
        tol = {"lower": _mm(item["lower"] + shift), "upper": _mm(item["upper"] + shift)}
        src = _src(item)
        if shift:
            src["cad_diameter"] = _mm(g[3])
        if g[4] == _HOLE_SIDE:
            h = _hole_of(ctx.feats, g, ctx.size)
            if h is None:
                return [], f"no hole of `info --features` on the axis of face:{g[0][0]}"
            out.append({"name": ctx.name(f"{item['id']}_diameter_{h.id.replace(':', '')}"),
                        "type": "hole", "feature": h.id, "diameter": tol, "pmi": src})
        else:
            # a boss the CAD splits into several faces (two half-cylinders) is one cylinder
            where = ({"feature": f"face:{g[0][0]}"} if len(g[0]) == 1 else
                     {"faces": [f"face:{f}" for f in g[0]]})
            out.append({"name": ctx.name(f"{item['id']}_diameter_face{g[0][0]}"),
                        "type": "cylinder", **where, "diameter": tol, "pmi": src})
    return out, ""


def _row(item, ctx, entries, reason) -> dict:
    faces = [ctx.fmap.get(f) for f in item.get("faces", [])]
    row = {"id": item["id"], "kind": item["kind"], "type": item["type"],
           "faces": ["face:%d" % f if f is not None else "?" for f in faces],
           "entries": [e["name"] for e in entries] if entries else [], "reason": reason}
    if item.get("supplemental_note"):
        row["supplemental_note"] = item["supplemental_note"]
    if item["kind"] == "geometric_tolerance":
        row["value"] = item["value"]
        row["datums"] = "|".join(d["name"] for d in item["datums"])
        row["modifiers"] = [m for m in ([item["material"]] if item["material"] else [])
                            + ([item["value_type"]] if item["value_type"] != "None" else [])
                            + item["modifiers"]]
    elif item["kind"] == "dimension":
        row["value"] = item["nominal"]
        row["limits"] = None if item["lower"] is None else [_mm(item["lower"]), _mm(item["upper"])]
    else:
        row["name"] = item["name"]
        row["targets"] = [f"{t['type']} {t['number']}" for t in item["targets"]]
    return row


def _unused_datum(name: str, ctx, unsupported: list) -> str:
    """Why a datum the plan could fit (its ``datums`` entry, e.g. a plane of several faces,
    a width's median plane) is not in the plan: only unchecked items reference it."""
    spec = ctx.datum_specs.get(name)
    if spec is None:
        return ""
    ids = [u["pmi"]["id"] for u in unsupported if name in
           re.split(r"[|\-]", u["pmi"].get("datums", "") or "")]
    if not ids:
        return ""
    what = spec.get("kind", "datum")
    n = len(spec.get("faces") or [])
    return (f"datum {name} ({what}" + (f" of {n} faces" if n > 1 else "") + ") is referenced "
            f"only by PMI items the plan does not check ({', '.join(ids)})")


def _failure(what: str, exc: Exception) -> str:
    return (f"{what} failed ({type(exc).__name__}: {exc}); it is not checked: inspect it by "
            "hand (an error of shapeverify on this file's PMI: please report it with the file)")


def _guarded(plan_item, item, *args, what: str = "planning it"):
    """``plan_item(item, *args)`` -- (entries or spec, reason) -- or, if it raises, (empty,
    the error as the reason): a PMI item that the plan's code cannot handle is listed as not
    checked, never lost, and never costs the file's other items (a file from another CAD
    system encodes what the NIST files we test on do not)."""
    try:
        return plan_item(item, *args)
    except Exception as exc:        # noqa: BLE001 -- reported as the item's reason
        logger.warning("PMI %s (%s %s): %s failed: %s: %s", item.get("id"), item.get("kind"),
                       item.get("type"), what, type(exc).__name__, exc)
        return (None if what == "datum" else []), _failure(
            "planning it" if what != "datum" else "reading this datum's feature", exc)


def pmi_plan(path, *, model=None, pmi=None, timeout: float | None = 600.0) -> PmiPlan:
    """The plan (and the rows of ``info --pmi``) from a STEP file's semantic PMI.

    Parameters
    ----------
    path : str or Path
        STEP AP242 file with semantic PMI.
    model : Model, optional
        The file's model, when already loaded (else :func:`shapeverify.cad.load.load_model`).
    pmi : dict, optional
        What :func:`shapeverify.cad.pmi.read_pmi` returned for the file (else it is read).
    timeout : float, optional
        Seconds for the OpenCASCADE read of the PMI.

    Returns
    -------
    PmiPlan

    Raises
    ------
    CADImportError
        The file cannot be read, or its PMI faces cannot be tied to the model's.
    """
    from ..cad.pmi import read_pmi

    path = Path(path)
    if pmi is None:
        pmi = read_pmi(path, timeout=timeout)
    if model is None:
        from ..cad.load import load_model

        model = load_model(path)
    model = getattr(model, "model", model)
    fmap = _face_map(pmi, model)
    # PMI on supplemental faces (outside the solid, never scanned) onto the solid faces under them
    pmi = remap_supplemental(pmi, model, fmap)
    ctx = _Ctx(pmi, model, fmap)
    datums = {d["name"]: d for d in pmi["datums"]}
    for name, d in datums.items():
        spec, reason = _guarded(_datum_spec, d, ctx, what="datum")
        if spec is None:
            ctx.datum_why[name] = reason
        else:
            ctx.datum_specs[name] = spec
    try:
        alignment, drf, why = _alignment(ctx, datums)
    except Exception as exc:        # noqa: BLE001 -- every datum says why; a best fit stands
        logger.warning("%s: the alignment from the PMI failed: %s: %s", path.name,
                       type(exc).__name__, exc)
        alignment, drf = {"type": "best_fit", "faces": "all"}, None
        why = {n: _failure("setting up the datum reference frame", exc) for n in datums}
    chars, unsupported, rows = [], [], []
    used = set(drf or ())
    for item in pmi["tolerances"]:
        entries, reason = _guarded(_tolerance, item, ctx, drf, why)
        chars.extend(entries)
        if not entries:
            unsupported.append({"pmi": _src(item), "reason": reason})
        rows.append(_row(item, ctx, entries, reason))
    for item in pmi["dimensions"]:
        entries, reason = _guarded(_dimension, item, ctx)
        chars.extend(entries)
        if not entries:
            unsupported.append({"pmi": _src(item), "reason": reason})
        rows.append(_row(item, ctx, entries, reason))
    table = {n: ctx.datum_specs[n] for n in sorted(ctx.used_datums)}
    common = {p for n in table for p in n.split("-")}
    for name, d in datums.items():
        if name in used or name in table or name in common:
            rows.append(_row(d, ctx, [{"name": "alignment" if name in used else "datums"}], ""))
            continue
        reason = (ctx.datum_why.get(name) if d["targets"] else None) or \
            _unused_datum(name, ctx, unsupported) or why.get(name) or (
            f"datum {name} is not in the plan's alignment (the plan aligns on one datum "
            f"reference frame: {'|'.join(drf) if drf else 'best fit'})")
        unsupported.append({"pmi": _src(d), "reason": reason})
        rows.append(_row(d, ctx, [], reason))
    data = {"units": "mm", "part": path.name, "alignment": alignment,
            "characteristics": chars, "unsupported": unsupported}
    if pmi.get("unread"):
        data["unread"] = [{"pmi": {k: u[k] for k in ("kind", "type", "name", "entity")},
                           "reason": u["reason"]} for u in pmi["unread"]]
        rows.extend({"id": u["entity"], "kind": u["kind"], "type": u["type"], "faces": [],
                     "entries": [], "reason": u["reason"], "unread": True}
                    for u in pmi["unread"])
    if table:
        data["datums"] = table
    plan = load_plan(data)
    logger.info("%s: plan from PMI: %d characteristics, %d PMI items unsupported, alignment %s",
                path.name, len(chars), len(unsupported), alignment["type"])
    return PmiPlan(plan, data, rows, pmi)


def plan_from_pmi(path, *, model=None, timeout: float | None = 600.0) -> Plan:
    """The inspection plan of a STEP AP242 file's semantic PMI (see the module docstring).

    Parameters
    ----------
    path : str or Path
        STEP AP242 file with semantic PMI.
    model : Model, optional
        The file's model, when already loaded.
    timeout : float, optional
        Seconds for the OpenCASCADE read of the PMI.

    Returns
    -------
    Plan
        Validated; ``plan.unsupported`` lists what it does not check and why.
    """
    return pmi_plan(path, model=model, timeout=timeout).plan


def plan_yaml(result: PmiPlan) -> str:
    """The plan as YAML text (what ``shapeverify plan -o plan.yaml`` writes)."""
    head = (f"# inspection plan from the semantic PMI of {result.data['part']} "
            "(shapeverify plan)\n")
    return head + yaml.safe_dump(result.data, sort_keys=False, allow_unicode=True, width=100)
