"""Profile of a line (ASME Y14.5 §11, ISO 1101 §18.5): the line elements of a surface in
sections parallel to a plane, each within a two-dimensional profile zone.

The sections are the planes ``(x - 0) . normal = s`` for ``s`` in ``sections`` (mm along the
unit ``normal`` in the model frame; default: ``count`` planes evenly over the faces' points'
extent along ``normal``, inset by the slab).  A section's line element is sampled by the scan
points within ``slab`` mm of the plane (a slab of width ``2 slab``); its profile value is
``2 max |d|`` (the zone of width ``t`` centred on the true profile holds it iff ``2 max |d|
<= t``), ``d`` each point's signed distance from the CAD faces.  The characteristic's value is
the largest over the sections (sections with fewer than :data:`MIN_POINTS` points are skipped
and counted).  With ``datums``, the points are moved into that datum reference frame first
(:mod:`.drf`) and their deviations taken again from the CAD (exact closest points), as a
surface profile in a DRF; without, the plan's alignment places them (no per-section refit:
the zone is located, as a profile with datums).

Uncertainty (k) as for a surface profile: ``2 z_n sigma`` (the k-level quantile of the
largest of the ``n`` noisy deviations of the deciding section) combined with the DRF's part.
"""
from __future__ import annotations

import numpy as np

__all__ = ["section_offsets", "sections_profile", "eval_line_profile", "MIN_POINTS"]

#: fewest points of a section's slab for its line element to be measured
MIN_POINTS = 3


def section_offsets(s: np.ndarray, count: int, slab: float) -> np.ndarray:
    """``count`` section offsets evenly over ``[min s + slab, max s - slab]`` (one: the middle)."""
    lo, hi = float(s.min()) + slab, float(s.max()) - slab
    if count == 1 or hi <= lo:
        return np.array([0.5 * (float(s.min()) + float(s.max()))])
    return np.linspace(lo, hi, count)


def sections_profile(X: np.ndarray, d: np.ndarray, normal, offsets, slab: float,
                     min_points: int = MIN_POINTS) -> tuple[float, int, list]:
    """(value, index of the deciding section or -1, per section ``{offset, n, value}``).

    X : (n, 3) points (model frame), d : (n,) their signed deviations, normal : the sections'
    normal (normalised here), offsets : section planes along it, slab : half-width (mm)."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    s = np.asarray(X, float) @ n
    d = np.asarray(d, float)
    per, best, at = [], -1.0, -1
    for k, o in enumerate(np.asarray(offsets, float)):
        m = np.abs(s - o) <= slab
        cnt = int(m.sum())
        v = 2.0 * float(np.abs(d[m]).max()) if cnt >= min_points else None
        per.append({"offset": float(o), "n": cnt, "value": v})
        if v is not None and v > best:
            best, at = v, k
    return (best if at >= 0 else float("nan")), at, per


def eval_line_profile(c, ctx):
    """line_profile (module docstring)."""
    from .alignment import face_indices
    from .evaluate import _not_measured
    from .datum_noise import datum_u
    from .gdt import _frame_points, _result
    from .gdt import _on
    from .support import extreme_quantile

    fidx = face_indices(ctx.prep.model, c.faces)
    fl = None if fidx is None else fidx.tolist()
    X, m, drf = _frame_points(c, ctx, fl)
    if X.shape[0] == 0:
        return _not_measured(c, "no scan points on the profile's faces")
    if drf is not None:
        cl = ctx.prep.closest(X, exact=True)
        d, nrm = np.asarray(cl.distances, float), np.asarray(cl.normals, float)
    else:
        d, nrm = np.asarray(ctx.S.d, float)[_on(ctx, fl)], np.zeros_like(X)
    ok = np.isfinite(d)
    X, d, nrm = X[ok], d[ok], nrm[ok]
    n = np.asarray(c.normal, float)
    n = n / np.linalg.norm(n)
    offsets = (np.asarray(c.sections, float) if c.sections is not None
               else section_offsets(X @ n, c.count, c.slab))
    value, at, per = sections_profile(X, d, n, offsets, c.slab)
    if at < 0:
        return _not_measured(c, f"no section has {MIN_POINTS} scan points within "
                                f"{c.slab:g} mm of its plane")
    zq = extreme_quantile(per[at]["n"], ctx.k)
    # the datums' noise moves the points along their CAD normals (:mod:`.datum_noise`)
    Ud = datum_u(drf, ctx, X, nrm[:, None])
    U = float(np.hypot(2.0 * zq * ctx.S.noise, Ud))
    details = {"sections": per, "deciding_section": float(per[at]["offset"]),
               "normal": n.tolist(), "slab": float(c.slab), "n": int(d.size),
               "skipped_sections": sum(p["value"] is None for p in per),
               "noise": ctx.S.noise, "extreme_quantile": zq, "faces": fl or "all",
               "u_datums": Ud}
    return _result(c, ctx, value, U, details, drf, 0.0, float(c.tol))
