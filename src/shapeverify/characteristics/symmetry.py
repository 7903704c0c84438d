"""Symmetry (ASME Y14.5-2009 section 7.7.2): all median points of opposed elements of a width
feature (a tab or a slot: two opposite parallel planar sides) lie within two parallel planes
``tol`` apart, centred on the datum centre plane (the feature's true centre plane: the plan
checks that the CAD centres the feature there).

On a scan, in the DRF's frame (the datum centre plane on its nominal place): the median points
are those of :func:`.median_plane.median_points` (opposed elements taken along the width's CAD
normal ``u``, the other side's height interpolated linearly); the zone is fixed in place and
orientation by the datums (a location tolerance: it neither turns nor moves), so the value is
``2 max |u . m - c|`` over the median points ``m`` (``c``: the true centre plane's offset
along ``u``) -- the width of the narrowest zone centred on the true centre plane holding them.

Lengths in mm.
"""
from __future__ import annotations

import numpy as np

__all__ = ["symmetry_value", "eval_symmetry"]


def symmetry_value(X1, X2, u, centre: float) -> tuple[float, np.ndarray]:
    """(``2 max |u . m - centre|``, the median points ``m``) of a width whose sides' points are
    ``X1``, ``X2`` (``u``: unit normal of the width, ``centre``: the true centre plane's offset
    along it).

    Example
    -------
    >>> import numpy as np
    >>> g = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2)
    >>> X1 = np.column_stack([np.full(25, 2.1), g]); X2 = np.column_stack([np.full(25, -1.9), g])
    >>> round(symmetry_value(X1, X2, [1.0, 0, 0], 0.0)[0], 9)    # centred at 0.1: 2 x 0.1
    0.2
    """
    from .median_plane import median_points

    u = np.asarray(u, np.float64) / np.linalg.norm(u)
    M = median_points(X1, X2, u)
    return 2.0 * float(np.abs(M @ u - centre).max()), M


def eval_symmetry(c, ctx):
    """symmetry of a width's median points about the datum centre plane (module docstring)."""
    from .evaluate import _not_measured
    from .datum_noise import datum_u
    from .gdt import _faces, _on, _result, drf_of
    from .position_zones import width_sides
    from .support import extreme_quantile

    fidx = _faces(c, ctx)
    A, B, u, true, width, slot = width_sides(ctx.feats, fidx)
    drf = drf_of(c.datums, ctx)
    XA, XB = (drf.apply(ctx.S.X[_on(ctx, s)]) for s in (A, B))
    if XA.shape[0] < 3 or XB.shape[0] < 3:
        return _not_measured(c, f"fewer than 3 scan points on a side of the width (faces {A}: "
                                f"{XA.shape[0]}, {B}: {XB.shape[0]})")
    value, M = symmetry_value(XA, XB, u, true)
    off = M @ u - true
    zq = extreme_quantile(max(M.shape[0], 2), ctx.k)
    # a median point's height is the mean of two noisy heights (sigma / sqrt(2)); the value
    # doubles it.  The datums' noise moves the median points along u (:mod:`.datum_noise`)
    Ud = datum_u(drf, ctx, M, np.asarray(u, float)[None])
    U = float(np.hypot(2.0 * zq * ctx.S.noise / np.sqrt(2.0), Ud))
    return _result(c, ctx, value, U,
                   {"faces": fidx, "sides": {"A": A, "B": B}, "direction": u.tolist(),
                    "feature": "slot" if slot else "tab", "cad_width": width,
                    "true_centre": true, "n_sides": [int(XA.shape[0]), int(XB.shape[0])],
                    "n_median_points": int(M.shape[0]),
                    "median_offset_range": [float(off.min()), float(off.max())],
                    "definition": "median points of opposed elements (ASME Y14.5-2009 "
                                  "7.7.2) in two parallel planes centred on the datum centre "
                                  "plane: twice the largest distance from it",
                    "noise": ctx.S.noise, "u_datums": Ud,
                    "excluded": ctx.S.excluded(fidx)}, drf)
