"""PMI on supplemental geometry, mapped onto the part (NIST FTC 08, FTC 10, CTC 02 e2).

A file's supplemental faces (:attr:`shapeverify.cad.model.Model.supplemental`: open shells or
free faces beside the part's solid) keep their face numbers, so the PMI tied to them still
names them, but a scan never holds them (no model point, no closest-point answer lies on one).
The plan puts what the PMI says of such a face on the faces of the solid it lies on: the
supplemental face is sampled (a grid of its trimmed domain) and each sample projected onto
every face of the solid near it; a sample lies on a solid face when its foot is within
:func:`on_tolerance` and inside that face's trimmed domain.  A supplemental face none of whose
samples lies on the solid (NIST FTC 10's thread faces, 1.25-1.69 mm off the solid) is a
construction surface off the part: the plan drops it from the item's faces with a note.
"""
from __future__ import annotations

import numpy as np

#: samples per parameter direction of a supplemental face (before trimming)
GRID = 15


def on_tolerance(size: float) -> float:
    """How far (mm) a supplemental face's sample may lie from a solid face and count as on it:
    1e-5 of the part's size, at least 1e-3 mm (a file's faces that share a surface agree to
    its modelling tolerance, far below this; FTC 10's construction faces are 1.25 mm off)."""
    return max(1e-3, 1e-5 * float(size))


def _samples(face) -> tuple[np.ndarray, np.ndarray]:
    """(points, unit normals) of a grid strictly inside the face's parameter box, kept where the
    trimmed domain holds them (the box's rim left out: points on an edge lie on the faces
    beside it too)."""
    (a0, a1), (b0, b1) = face.uv_bounds
    g = np.stack(np.meshgrid(np.linspace(a0, a1, GRID + 2)[1:-1],
                             np.linspace(b0, b1, GRID + 2)[1:-1]), -1).reshape(-1, 2)
    g = g[face.contains(g)]
    return face.evaluate(g), face.normal(g)


def _box(face, cache: dict, k: int):
    if k not in cache:
        c = np.asarray(face.surface.control, float).reshape(-1, 3)
        cache[k] = (c.min(0), c.max(0))   # a NURBS surface lies in its control net's box
    return cache[k]


def supplemental_map(model) -> dict:
    """{supplemental face (model number): {"on": [solid faces], "covered": fraction of its
    samples on them, "off": largest distance of a sample from the solid faces tried (mm),
    "n": samples}} for every supplemental face of ``model``."""
    from .pmi_datums import project_on_face

    supp = tuple(getattr(model, "supplemental", ()) or ())
    if not supp:
        return {}
    tol = on_tolerance(model.size)
    part = [k for k in range(len(model.faces)) if k not in set(supp)]
    boxes: dict = {}
    out = {}
    for s in supp:
        P, N = _samples(model.faces[s])
        if not len(P):
            out[int(s)] = {"on": [], "covered": 0.0, "off": float("nan"), "n": 0}
            continue
        lo, hi = P.min(0), P.max(0)
        on = np.zeros(len(P), bool)
        best = np.full(len(P), np.inf)
        hits = []
        for k in part:
            face = model.faces[k]
            blo, bhi = _box(face, boxes, k)
            if np.any(hi < blo - tol) or np.any(lo > bhi + tol):
                continue
            uv, dist = project_on_face(face, P)
            # on the face: the foot inside its trimmed domain, the same surface (normals
            # along each other: a face that meets it at an angle shares an edge only)
            along = np.abs(np.einsum("ij,ij->i", face.normal(uv), N)) > 1 - 1e-6
            d = np.where(face.contains(uv) & along, np.abs(dist), np.inf)
            best = np.minimum(best, d)
            here = d <= tol
            if here.any():
                hits.append((k, int(here.sum())))
                on |= here
        out[int(s)] = {"on": sorted(k for k, _ in hits), "covered": float(on.mean()),
                       "off": float(best.max()),
                       "n": int(len(P))}
    return out


def _fmt(faces) -> str:
    return ", ".join(map(str, faces))


def _remap_list(faces, fmap, inv, smap, log):
    """``faces`` (PMI numbers) with each supplemental face replaced by the solid faces it lies
    on (none: dropped); ``log`` collects (PMI face, [solid PMI faces])."""
    out = []
    for f in faces:
        m = fmap.get(f)
        if m is None or m not in smap:
            new = [f]
        else:
            new = [inv[k] for k in smap[m]["on"] if k in inv]
            log.append((f, new))
        out.extend(x for x in new if x not in out)
    return out


def remap_supplemental(pmi: dict, model, fmap: dict) -> dict:
    """``pmi`` (what :func:`shapeverify.cad.pmi.read_pmi` returned) with every face number of a
    supplemental face (in the items' ``faces``, ``faces2``, datum targets' ``faces`` and
    ``on_faces`` and their edges' ``on_faces``) replaced by the solid faces it lies on
    (:func:`supplemental_map`), or dropped when it lies on none.  A changed item carries
    ``from_supplemental`` (the supplemental PMI faces, ascending) and ``supplemental_note``
    (what became of each); one whose faces were all dropped also ``supplemental_reason``.
    The input is not modified; without supplemental faces it is returned as it is."""
    import copy

    smap = supplemental_map(model)
    if not smap:
        return pmi
    inv = {v: k for k, v in fmap.items()}
    out = dict(pmi)
    for key in ("tolerances", "dimensions", "datums"):
        items = []
        for it in pmi.get(key, ()):
            log: list = []
            new = copy.deepcopy(it)
            for fk in ("faces", "faces2"):
                if fk in new:
                    new[fk] = _remap_list(new[fk], fmap, inv, smap, log)
            for t in new.get("targets", ()) or ():
                for fk in ("faces", "on_faces"):
                    if fk in t and t[fk]:
                        t[fk] = _remap_list(t[fk], fmap, inv, smap, log)
                for e in t.get("edges", ()) or ():
                    if isinstance(e, dict) and e.get("on_faces"):
                        e["on_faces"] = _remap_list(e["on_faces"], fmap, inv, smap, log)
            if not log:
                items.append(it)
                continue
            seen, notes = set(), []
            for f, to in log:
                if f in seen:
                    continue
                seen.add(f)
                s = smap[fmap[f]]
                if to:
                    cov = (f", {s['covered']:.0%} of it" if s["covered"] < 0.995 else "")
                    notes.append(f"face {f} lies on face{'s' if len(to) > 1 else ''} "
                                 f"{_fmt(to)}{cov}")
                elif s["n"] == 0:
                    notes.append(f"face {f} is too small for a {GRID} x {GRID} grid of its "
                                 "domain to sample: left out")
                else:
                    notes.append(f"face {f} lies on no face of the solid (a construction "
                                 "surface off the part): left out")
            new["from_supplemental"] = sorted(seen)
            new["supplemental_note"] = ("supplemental geometry (outside the solid, never "
                                        "scanned): " + "; ".join(notes))
            if any(fk in it and it[fk] and not new[fk] for fk in ("faces", "faces2")):
                new["supplemental_reason"] = (
                    f"it is attached to supplemental face(s) {_fmt(sorted(seen))} only, which "
                    "lie on no face of the part's solid (construction surfaces off the part: "
                    "no scan holds them)")
            items.append(new)
        out[key] = items
    return out
