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

_TYPES = {"Point": "point", "Line": "line", "Circle": "circle", "Rectangle": "rectangle",
          "CircularCurve": "circular_line"}


def _line_on_edge(t: dict, what: str, ctx) -> tuple[dict | None, str, str]:
    """(target entry, note, '') of a line target attached to an edge drawn on one face (NIST
    FTC 06 J, K): the line is the edge's -- its middle, direction and length -- on the face it
    lies on; the note says how the file's target parameters compare; or (None, '', why)."""
    import numpy as np

    es = t.get("edges") or []
    if len(es) != 1 or es[0]["curve"] != "Line":
        return None, "", (f"{what} is attached to {len(es)} edges "
                          f"({', '.join(e['curve'] for e in es) or 'none read'}), not to one "
                          "straight edge")
    e = es[0]
    on = e.get("on_faces") or []
    if len(on) != 1:
        where = (f"between faces {', '.join(map(str, e['faces']))}" if e["faces"] else
                 f"on {len(on)} faces" if on else "on no face of the part")
        return None, "", f"{what} is attached to an edge {where}, not drawn on one face"
    face = ctx.fmap.get(on[0])
    if face is None:
        return None, "", f"{what}: its face could not be imported"
    P = np.asarray(e["points"], float)
    a, b = P[0], P[-1]
    L = float(np.linalg.norm(b - a))
    if not L > 0:
        return None, "", f"{what}: its edge has no length"
    u = (b - a) / L
    entry = {"type": "line", "at": [float(x) for x in 0.5 * (a + b)], "face": f"face:{face}",
             "direction": [float(x) for x in u], "length": L}
    notes = []
    if "at" in t:
        at = np.asarray(t["at"], float)
        ends = min(np.linalg.norm(at - a), np.linalg.norm(at - b))
        along = [k for k in ("direction", "xdirection")
                 if abs(abs(np.asarray(t[k], float) @ u) - 1) < 1e-6]
        start = ("starts the line at an end of the edge" if ends < 1e-6 * max(L, 1.0)
                 else "is off the edge's ends")
        notes.append(f"the file's placement {start}"
                     + (f", along its {along[0]}" if along else ", along neither of its axes"))
        if abs(t["length"] - L) > 1e-6 * L:
            r = t["length"] / L
            inch = abs(r - 25.4) < 1e-6 * r
            notes.append(f"its target length reads {t['length']:.6g} mm, {r:.6g} times the "
                         "edge's" + (" (the file labels a length in mm as inch)" if inch else ""))
    note = (f"target {t['number']}: the line of its edge ({L:.6g} mm on face {face}); "
            + "; ".join(notes))
    return entry, note, ""


def project_on_face(face, P) -> tuple:
    """``(uv, dist)`` of points ``P`` (n, 3) projected on ``face``'s surface, each started from
    the nearest node of a 41 x 41 grid over the face's uv box (a target's rim, a supplemental
    face's samples).  ``dist`` is signed along the surface normal; whether ``uv`` lies in the
    trimmed face is the caller's test (``face.contains``)."""
    import numpy as np

    from ..fitting.surfaces import project_to_surface

    (a0, a1), (b0, b1) = face.uv_bounds
    g = np.stack(np.meshgrid(np.linspace(a0, a1, 41), np.linspace(b0, b1, 41)),
                 -1).reshape(-1, 2)
    G = face.evaluate(g)
    uv0 = g[np.argmin(((P[:, None] - G[None]) ** 2).sum(-1), axis=1)]
    return project_to_surface(face.surface, P, uv0)


def _area_on_face(t: dict, what: str, ctx) -> tuple[int | None, str, str]:
    """(PMI face number, note, '') of an area target (circle, rectangle) that the file attaches
    to no shape (NIST CTC 05 C1, D1: a placed rectangle only): the one planar face whose plane
    holds the target's placement (normal along its ``direction``) and whose trimmed domain holds
    its centre and its outline (the corners, or 8 points of the circle, each pulled 1 % towards
    the centre); or (None, '', why)."""
    import numpy as np

    at = np.asarray(t["at"], float)
    n = np.asarray(t["direction"], float)
    n /= np.linalg.norm(n)
    if t["type"] == "Rectangle":
        x = np.asarray(t["xdirection"], float)
        x = x - (x @ n) * n
        x /= np.linalg.norm(x)
        y = np.cross(n, x)
        hx, hy = 0.5 * float(t["length"]), 0.5 * float(t["width"])
        rim = [at + sx * hx * x + sy * hy * y for sx in (-1, 1) for sy in (-1, 1)]
    else:
        e = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
        e /= np.linalg.norm(e)
        f = np.cross(n, e)
        r = 0.5 * float(t["length"])
        rim = [at + r * (np.cos(a) * e + np.sin(a) * f) for a in np.linspace(0, 2 * np.pi, 9)[:-1]]
    P = np.array([at] + [at + 0.99 * (q - at) for q in rim])
    tol = max(1e-6 * ctx.size, 1e-6)
    inv = {v: k for k, v in ctx.fmap.items()}
    hits = []
    supp = set(getattr(ctx.model, "supplemental", ()))   # outside the solid: not the part
    for k, ft in enumerate(ctx.feats):
        if ft.kind != "plane" or abs(abs(float(ft.axis @ n)) - 1) > 1e-6 \
                or abs(float((at - ft.center) @ ft.axis)) > tol or k not in inv or k in supp:
            continue
        face = ctx.model.faces[k]
        uv, dist = project_on_face(face, P)
        inside = face.contains(uv) & (np.abs(dist) <= tol)
        if inside[0]:
            hits.append((k, int(inside.sum()) - 1))
    if len(hits) != 1:
        return None, "", (f"{what} is attached to no shape, and its placement lies on "
                          f"{len(hits)} planar faces of the part (one expected)")
    k, n_in = hits[0]
    if n_in != len(rim):
        return None, "", (f"{what} is attached to no shape; its centre lies on face {k} but "
                          f"{len(rim) - n_in} of its outline's {len(rim)} points are off it")
    note = (f"target {t['number']}: attached to no shape in the file; its {t['type'].lower()} "
            f"(centre and outline) lies on planar face {k}, the only face whose plane and "
            "trimmed domain hold it")
    return inv[k], note, ""


def _point_on_face(t: dict, what: str, ctx) -> tuple[int | None, str, str]:
    """(PMI face number, note, '') of a point target that the file attaches to a vertex -- a
    standalone point (NIST CTC 02 e2, CATIA's 'Point.5' ...) -- not to a face: the one face whose
    trimmed domain holds the point (within 1e-6 of the part's size, of the domain on its
    edge); on an edge, the one whose
    normal there is along the target's ``direction``; or (None, '', why)."""
    import numpy as np

    at = np.asarray(t["at"], float)
    tol = max(1e-6 * ctx.size, 1e-6)
    inv = {v: k for k, v in ctx.fmap.items()}
    hits = []
    supp = set(getattr(ctx.model, "supplemental", ()))   # outside the solid: not the part
    for k, face in enumerate(ctx.model.faces):
        if k not in inv or k in supp:
            continue
        c = np.asarray(face.surface.control, float).reshape(-1, 3)
        if np.any(at < c.min(0) - tol) or np.any(at > c.max(0) + tol):
            continue                   # a NURBS surface lies in its control net's box
        (a0, a1), (b0, b1) = face.uv_bounds
        uv, dist = project_on_face(face, at[None])
        ring = uv + 1e-7 * np.array([a1 - a0, b1 - b0]) * np.array(
            [[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]])
        if abs(float(dist[0])) <= tol and face.contains(ring).any():   # on its edge too
            hits.append((k, uv))
    if len(hits) > 1 and t.get("direction") is not None:
        n = np.asarray(t["direction"], float)
        n = n / np.linalg.norm(n)
        hits = [(k, uv) for k, uv in hits
                if abs(abs(float(ctx.model.faces[k].normal(uv)[0] @ n)) - 1) < 1e-6]
    if len(hits) != 1:
        return None, "", (f"{what} is attached to a vertex that lies on {len(hits)} faces of "
                          "the part along its direction (one expected)")
    k = hits[0][0]
    return inv[k], (f"target {t['number']}: attached to a point (vertex) in the file; it lies "
                    f"on face {k}, the only face whose trimmed domain holds it"), ""


def targets_spec(d: dict, ctx, src: dict) -> tuple[dict | None, str]:
    """(the ``datums`` entry of a datum set up from datum targets, '') or (None, why not).

    A line target attached to an edge drawn on a face takes the edge's line
    (:func:`_line_on_edge`); a circular-curve target (read from the STEP entities by
    :mod:`shapeverify.cad.pmi_iiru`) is a ``circular_line`` on the faces its circle lies on."""
    out, notes = [], []
    for t in d["targets"]:
        what = f"datum {d['name']}: target {d['name']}{t['number']} ({t['type']})"
        kind = _TYPES.get(t["type"])
        if kind is None:
            return None, (f"{what} is of a type not set up yet (point, line, circle, rectangle, "
                          "circular curve)")
        if t.get("target_reason"):
            return None, f"{what}: {t['target_reason']}"
        if kind == "line" and not t["faces"] and t.get("edges"):
            e, note, why = _line_on_edge(t, what, ctx)
            if e is None:
                return None, why
            out.append(e)
            notes.append(note)
            continue
        if kind == "circular_line":
            faces = [ctx.fmap.get(f) for f in t.get("on_faces") or []]
            if not faces or any(f is None for f in faces):
                return None, f"{what}: its circle lies on no imported face"
            out.append({"type": kind, "at": [float(x) for x in t["at"]],
                        "faces": [f"face:{f}" for f in faces],
                        "direction": [float(x) for x in t["direction"]],
                        "length": float(t["length"])})
            notes.append(f"target {t['number']}: {t['attached']}")
            continue
        if "at" not in t:
            return None, f"{what}: the file gives no position for it (no target parameters)"
        if kind in ("circle", "rectangle") and not t["faces"] and not t.get("other"):
            face, note, why = _area_on_face(t, what, ctx)
            if face is None:
                return None, why
            t = {**t, "faces": [face]}
            notes.append(note)
        if kind == "point" and not t["faces"] and set(t.get("other") or ()) == {"vertex"}:
            face, note, why = _point_on_face(t, what, ctx)
            if face is None:
                return None, why
            t = {**t, "faces": [face]}
            notes.append(note)
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
    if notes:
        src = {**src, "targets_from_geometry": notes}
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


def _diameter(letter: str, ctx) -> dict | None:
    """The toleranced diameter (Size_Diameter with limits) on every face of a PMI datum."""
    from .pmi_plan import _mm

    want = set(next(d for d in ctx.pmi["datums"] if d["name"] == letter)["faces"])
    size = next((x for x in ctx.pmi["dimensions"] if x["type"] == "Size_Diameter"
                 and x["lower"] is not None and want and want <= set(x["faces"])), None)
    if size is None:
        return None
    return {"nominal": _mm(size["nominal"]), "lower": _mm(size["lower"]),
            "upper": _mm(size["upper"])}


#: tolerances that hold a datum feature's axis in orientation to the datums before it
_ORIENTATION = ("Perpendicularity", "Parallelism", "Angularity")


def _frame_labels(item: dict) -> list[str]:
    """A tolerance's datum reference frame as labels (common datums joined: ``E-F``)."""
    ds = item.get("datums") or []
    return ["-".join(d["name"] for d in ds if d["order"] == o)
            for o in sorted({d["order"] for d in ds})]


def derived_boundary(letter: str, ctx, before: list, pattern: bool) -> dict | None:
    """The MMB / LMB of the datum feature of size ``letter`` whose size has no limits in the
    file (ASME Y14.5-2009 4.11.6: the boundary is worked out from the feature's MMC -- here its
    nominal size, the only size the file gives -- and the geometric tolerances that hold it to
    the datums of higher precedence, ``before`` in the frame that references it):

    * the candidates: tolerances with a diameter zone on the feature's faces whose frame starts
      with ``before`` (the same datums, none at MMB/LMB) -- a position (it bounds the feature's
      axis in every direction relative to those datums, and the pattern's features relative to
      each other); an orientation tolerance only for a single feature (a pattern's spacing is
      not held by it) after planes only (a hole square to a plane is then free in location);
      none for a primary single feature (MMB = MMC);
    * each candidate of zone ``t`` guarantees the boundary ``nominal - t`` of a hole (a pin of
      that diameter, at its basic place among the pattern's features, fits every conforming
      feature: the axis lies in the zone of diameter ``t``), ``nominal + t`` of a boss; the
      smallest ``t`` gives the largest (tightest) such boundary, the MMB.  The LMB mirrors it
      (``nominal + t`` of a hole, ``nominal - t`` of a boss).

    Returns the size entry (``nominal``, ``mmb``, ``lmb``, ``rule``), or None when the datum's
    faces are not one cylinder size (then the datum stays unsupported)."""
    import numpy as np

    from .pmi_plan import _cylinders, _mm

    datum = next(d for d in ctx.pmi["datums"] if d["name"] == letter)
    want = set(datum["faces"])
    faces = [ctx.fmap[f] for f in sorted(want) if f in ctx.fmap]
    groups, other = _cylinders(ctx.feats, ctx.model, faces)
    if not faces or len(groups) != 1 or other:
        return None
    cad_d, side = groups[0][3], groups[0][4]
    dim = next((x for x in ctx.pmi["dimensions"] if x["type"] == "Size_Diameter"
                and want and want <= set(x["faces"])), None)
    nominal = _mm(dim["nominal"]) if dim is not None else _mm(cad_d)
    said = (f"{dim['id']}'s nominal diameter {nominal:g} (no limits)" if dim is not None else
            f"its CAD diameter {nominal:g} (no size dimension)")
    single_after_planes = (not pattern and before
                           and all((ctx.datum_specs.get(b) or {}).get("kind") == "plane"
                                   for b in before))
    best = None
    for t in ctx.pmi["tolerances"]:
        if (t.get("value_type") != "Diameter" or not want <= set(t["faces"])
                or t.get("value") is None or not np.isfinite(t["value"])):
            continue
        if t["type"] == "Position":
            ok = pattern or bool(before)
        else:
            ok = t["type"] in _ORIENTATION and single_after_planes
        refs = [d for d in t.get("datums") or [] if d["order"] <= len(before)]
        if (not ok or _frame_labels(t)[:len(before)] != list(before)
                or any(d["modifiers"] for d in refs)):
            continue
        if best is None or t["value"] < best["value"]:
            best = t
    tol = _mm(best["value"]) if best is not None else 0.0
    hole = side == "hole"
    mmb, lmb = (nominal - tol, nominal + tol) if hole else (nominal + tol, nominal - tol)
    if min(mmb, lmb) <= 0:
        return None
    what = "hole" if hole else "boss"
    if best is None:
        how = (f"no diameter-zone position{'' if pattern else ' or orientation'} tolerance "
               f"holds it to {'|'.join(before) or 'the datums before it'}: MMB = MMC")
    else:
        how = (f"{best['id']}'s {best['type'].lower()} ⌀{tol:g} "
               f"({'|'.join(_frame_labels(best))}) holds it to {'|'.join(before) or 'its frame'}")
    rule = (f"ASME Y14.5-2009 4.11.6: datum {letter} ({what}) has no toleranced size; MMC = "
            f"{said}; {how}; MMB ⌀{_mm(mmb):g}, LMB ⌀{_mm(lmb):g}")
    return {"nominal": nominal, "mmb": _mm(mmb), "lmb": _mm(lmb), "rule": rule}


def datum_modifiers(item: dict, ctx, names: list) -> tuple[dict | None, str]:
    """({DRF datum name: 'M' | 'L'} of a tolerance's DRF ``names`` (common datums joined,
    ``H-J``), '') or (None, why not): each modified datum must be a hole or boss axis, or a
    pattern / common datum of them (every datum of a common one with the same modifier), each
    feature with a toleranced diameter (``Size_Diameter`` with limits on its faces), whose
    limits are then put into its ``datums`` entry (``size``, or ``face_sizes`` for features of
    different sizes: the MMB/LMB, :mod:`.datum_shift`)."""
    out = {}
    for order in sorted({d["order"] for d in item["datums"]}):
        group = [d for d in item["datums"] if d["order"] == order]
        if not any(d["modifiers"] for d in group):
            continue
        label = "-".join(d["name"] for d in group)
        mods = {tuple(d["modifiers"]) for d in group}
        flat = [m for d in group for m in d["modifiers"]]
        other = [m for m in flat if m not in _MATERIAL]
        mats = {_MATERIAL[m] for m in flat if m in _MATERIAL}
        if other or len(mats) != 1 or len(mods) != 1:
            return None, (f"datum modifiers of {label} ({'; '.join(d['name'] + ' ' + ', '.join(d['modifiers']) for d in group)}) are not applied "
                          "(MMB or LMB, the same on every datum of a common datum)")
        mat = mats.pop()
        what = "MMB" if mat == "M" else "LMB"
        name = label if len(group) > 1 else group[0]["name"]
        if name not in names:
            return None, f"datum {label} is not in the frame {'|'.join(names)}"
        spec = ctx.datum_specs.get(name)
        if spec is None:
            return None, ctx.datum_why.get(name, f"datum {name} is not in the file")
        if spec.get("kind") not in ("axis", "pattern"):
            return None, (f"datum {label} at {what} is a {spec.get('kind')} datum; its shift "
                          "is applied to hole and boss axes and patterns of them")
        sizes = {}
        for d in group:
            sz = _diameter(d["name"], ctx)
            if sz is None:      # no size limits: the boundary from the nominal and the GD&T
                sz = derived_boundary(d["name"], ctx, names[:names.index(name)],
                                      len(group) > 1 or spec.get("kind") == "pattern")
            if sz is None:
                return None, (f"datum {d['name']} at {what}: no toleranced diameter "
                              "(Size_Diameter) on its faces, and its faces are not one "
                              "cylinder whose nominal diameter could give the boundary")
            sizes[d["name"]] = sz
        if len({tuple(sorted(v.items())) for v in sizes.values()}) == 1:
            spec["size"] = next(iter(sizes.values()))
        else:       # a common datum of features of different sizes: per face
            spec["face_sizes"] = [sizes[d["name"]] for d in group
                                  for _ in ctx.datum_specs[d["name"]]["faces"]]
        out[name] = mat
    return out, ""
