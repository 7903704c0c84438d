"""The direction of a hole's two-parallel-planes position zone, read from where its feature
control frame is drawn (the file's graphical PMI; the semantic PMI carries no zone direction).

ASME Y14.5-2009 §7.7.3 (bidirectional positional tolerancing, rectangular coordinate method):
a position tolerance without ⌀ on a round hole is two parallel planes "equally disposed about
the true position", and the frame is attached to a dimension line: the zone applies in that
dimension line's direction (the planes are perpendicular to it).  A STEP AP242 file says so
only in its presentation: NIST CTC 03 (both editions) draws the hole's size as a linear
dimension across the hole along y (extension lines tangent to the hole, the dimension line
between them) and puts the 'Position.8' frame's leader on that dimension line.

:func:`frame_dimension_direction` finds, for the tolerance named ``name``, a presentation
(another annotation of the file) holding

* two parallel straight segments (extension lines) on the two lines tangent to the hole on
  opposite sides, ``(p - c) . u = +r`` and ``-r`` (``c``, ``r``: the hole's axis point and
  radius, ``u`` across the axis), and
* a straight segment along ``u`` (the dimension line) on which a vertex of the frame's own
  presentation lies (the leader's end),

and returns ``u``; None with the reason otherwise (no such drawing, or two that disagree).
Both encodings are read: AP242 e2 tessellated curve sets (``TESSELLATED_ANNOTATION_OCCURRENCE``
with a ``REPOSITIONED_TESSELLATED_ITEM`` placement) and e1 polylines
(``ANNOTATION_CURVE_OCCURRENCE`` of a ``GEOMETRIC_CURVE_SET``); coordinates in the file's
length unit, returned in mm.
"""
from __future__ import annotations

import re

import numpy as np

from .step_text import step_text

__all__ = ["presentation_polylines", "frame_dimension_direction"]

_REF = re.compile(r"#(\d+)")
_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _refs(s: str) -> list[int]:
    return [int(x) for x in _REF.findall(s)]


def _point(st, k: int) -> np.ndarray:
    a = st.calls(k).get("CARTESIAN_POINT") or st.calls(k).get("DIRECTION")
    return np.array([float(x) for x in _NUM.findall(a[1])], float)


def _placement(st, k: int):
    """(origin, x, y, z) of an AXIS2_PLACEMENT_3D."""
    a = st.calls(k)["AXIS2_PLACEMENT_3D"]
    o = _point(st, _refs(a[1])[0])
    z = _point(st, _refs(a[2])[0]) if _refs(a[2]) else np.array([0.0, 0.0, 1.0])
    x = _point(st, _refs(a[3])[0]) if _refs(a[3]) else np.array([1.0, 0.0, 0.0])
    z = z / np.linalg.norm(z)
    x = x - (x @ z) * z
    x = x / np.linalg.norm(x)
    return o, x, np.cross(z, x), z


def _curve_set(st, k: int, place) -> list:
    """Polylines of a TESSELLATED_CURVE_SET in the model frame."""
    a = st.calls(k)["TESSELLATED_CURVE_SET"]
    cl = st.calls(_refs(a[1])[0])["COORDINATES_LIST"]
    P = np.array([[float(v) for v in _NUM.findall(t)]
                  for t in re.findall(r"\(([^()]*)\)", cl[2])], float)[:, :3]
    if place is not None:
        o, x, y, z = place
        P = o + P[:, :1] * x + P[:, 1:2] * y + P[:, 2:3] * z
    out = []
    for seg in re.findall(r"\(([\d,\s]+)\)", a[2]):
        idx = [int(t) - 1 for t in seg.split(",") if t.strip()]
        if len(idx) >= 2:
            out.append(P[idx])
    return out


def _occurrence(st, k: int) -> list:
    """Polylines of an annotation occurrence (e2 tessellated or e1 polyline encoding)."""
    c = st.calls(k)
    out: list = []
    if "TESSELLATED_ANNOTATION_OCCURRENCE" in c:
        g = _refs(c["TESSELLATED_ANNOTATION_OCCURRENCE"][2])[0]
        gc = st.calls(g)
        rep = gc.get("REPOSITIONED_TESSELLATED_ITEM")
        place = _placement(st, _refs(rep[0])[0]) if rep else None
        items = gc.get("TESSELLATED_GEOMETRIC_SET")
        for it in _refs(items[0]) if items else []:
            if "TESSELLATED_CURVE_SET" in st.calls(it):
                out.extend(_curve_set(st, it, place))
    elif "ANNOTATION_CURVE_OCCURRENCE" in c:
        g = _refs(c["ANNOTATION_CURVE_OCCURRENCE"][2])[0]
        gc = st.calls(g)
        curves = _refs(gc["GEOMETRIC_CURVE_SET"][1]) if "GEOMETRIC_CURVE_SET" in gc else [g]
        for cv in curves:
            pl = st.calls(cv).get("POLYLINE")
            if pl:
                out.append(np.array([_point(st, p) for p in _refs(pl[1])], float))
    return out


def presentation_polylines(path) -> dict:
    """{definition entity id: [polylines (n, 3) in the file's unit]} of every draughting model
    item association of the file (the definition: a tolerance, a dimension or a shape aspect;
    its identified item: a draughting callout or an annotation occurrence)."""
    st = step_text(path)
    memo = st.memo.get("presentation_polylines")
    if memo is not None:
        return memo
    out: dict = {}
    for k, body in st.entities.items():
        if "DRAUGHTING_MODEL_ITEM_ASSOCIATION" not in body:
            continue
        c = st.calls(k)
        a = c.get("DRAUGHTING_MODEL_ITEM_ASSOCIATION_WITH_PLACEHOLDER") or \
            c.get("DRAUGHTING_MODEL_ITEM_ASSOCIATION")
        if not a or len(a) < 5 or not _refs(a[2]) or not _refs(a[4]):
            continue
        item = _refs(a[4])[0]
        ic = st.calls(item)
        occ = _refs(ic["DRAUGHTING_CALLOUT"][1]) if "DRAUGHTING_CALLOUT" in ic else [item]
        lines = out.setdefault(_refs(a[2])[0], [])
        for o in occ:
            try:
                got = _occurrence(st, o)
            except (KeyError, IndexError, ValueError):
                continue
            for g in got:
                if not any(g is x or (g.shape == x.shape and np.array_equal(g, x))
                           for x in lines):
                    lines.append(g)
    st.memo["presentation_polylines"] = out
    return out


def _tolerance_ids(st, name: str) -> list[int]:
    """Entity ids of the position tolerances named ``name``."""
    out = []
    for k, body in st.entities.items():
        if "POSITION_TOLERANCE" not in body:
            continue
        c = st.calls(k)
        g = c.get("GEOMETRIC_TOLERANCE") or c.get("POSITION_TOLERANCE")
        if g and g[0] == "'" + name.replace("'", "''") + "'":
            out.append(k)
    return out


def _segments(lines, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) (m, 3) of the non-degenerate straight pieces of polylines."""
    if not lines:
        return np.zeros((0, 3)), np.zeros((0, 3))
    A = np.concatenate([P[:-1] for P in lines]) * scale
    B = np.concatenate([P[1:] for P in lines]) * scale
    keep = np.linalg.norm(B - A, axis=1) > 1e-9
    return A[keep], B[keep]


def _touch(V, A, B, eps) -> np.ndarray:
    """Per segment (A[i], B[i]): whether a point of V lies within eps of it."""
    D = B - A
    t = np.clip(np.einsum("nmk,mk->nm", V[:, None, :] - A[None], D) / (D * D).sum(1), 0, 1)
    gap = np.linalg.norm(A[None] + t[..., None] * D[None] - V[:, None, :], axis=2)
    return (gap <= eps).any(axis=0)


def frame_dimension_direction(path, name: str, centre, axis, radius: float,
                              mm_per_unit: float = 1.0) -> tuple[np.ndarray | None, str]:
    """(unit direction across the hole's axis, description) of the dimension line the frame
    of position tolerance ``name`` is attached to (module docstring), or (None, reason).
    ``centre``, ``axis``, ``radius``: the hole (mm)."""
    st = step_text(path)
    ids = _tolerance_ids(st, name)
    if len(ids) != 1:
        return None, (f"{len(ids)} position tolerances named {name!r} in the file (one "
                      "needed to find its drawn frame)")
    pres = presentation_polylines(path)
    mine = [P * mm_per_unit for P in pres.get(ids[0], [])]
    if not mine:
        return None, f"the frame of {name!r} has no presentation in the file"
    verts = np.concatenate(mine)
    c, a, r = np.asarray(centre, float), np.asarray(axis, float), float(radius)
    a = a / np.linalg.norm(a)
    eps = 1e-3 * r + 0.01
    found = []
    for key, lines in pres.items():
        if key == ids[0]:
            continue
        A, B = _segments(lines, mm_per_unit)
        if not len(A):
            continue
        D = B - A
        L = np.linalg.norm(D, axis=1)
        U = D - np.outer(D @ a, a)
        across = np.linalg.norm(U, axis=1) >= 0.5 * L        # pieces across the axis
        if not across.any():
            continue
        cand = np.flatnonzero(across)
        cand = cand[_touch(verts, A[cand], B[cand], eps)]    # the frame's leader on it
        for i in cand:
            u = U[i] / np.linalg.norm(U[i])
            e = np.cross(a, u)                               # the extension lines' direction
            par = np.abs(np.abs((D / L[:, None]) @ e) - 1.0) <= 1e-3
            o1, o2 = (A - c) @ u, (B - c) @ u
            sides = {s for s in (1, -1)
                     if np.any(par & (np.abs(o1 - s * r) <= eps) & (np.abs(o2 - s * r) <= eps))}
            if sides == {1, -1}:
                found.append((u, key))
    if not found:
        return None, (f"the frame of {name!r} is not drawn on the dimension line of a "
                      "dimension across the hole (extension lines tangent to it on both "
                      "sides): no drawn direction either")
    u0 = found[0][0]
    if any(abs(float(u @ u0)) < 1.0 - 1e-6 for u, _ in found):
        return None, f"the frame of {name!r} touches dimension lines of different directions"
    u0 = (u0 if u0[int(np.argmax(np.abs(u0)))] > 0 else -u0) + 0.0
    return u0, (f"the frame {name!r} is drawn on the dimension line of the presentation of "
                f"entity #{found[0][1]} (its extension lines tangent to the hole on both "
                "sides): the zone applies along that dimension line (ASME Y14.5-2009 "
                "§7.7.3)")
