"""The derived median plane of a width (two opposite parallel planar sides: a tab or a slot),
ASME Y14.5-2009 section 1.3.23: the centre points of all line segments bounded by the feature,
the segments normal to the centre plane of its actual mating envelope.

On a scan the segments are taken along the width's CAD normal ``n`` (in the frame where the
part sits on its CAD pose, the mating envelope's centre plane differs from the CAD one by the
part's tilt: a first-order change of the median points' heights of the order of the feature's
form, second order in its angle): each side's points are written in the plane across ``n``
(coordinates ``u, v``) with their heights ``h = n . x``; at every point of one side the other
side's height is interpolated linearly on its Delaunay triangulation in ``u, v`` (points
outside the other side's hull have no opposed point and are left out); the median point is
at ``(u, v)`` with height ``(h_1 + h_2) / 2``.  Both sides' points give median points.

Orientation and position zones of a median plane are then the zones of these points
(:func:`.gdt_zones.planes_zone`).

Lengths in mm.
"""
from __future__ import annotations

import numpy as np

__all__ = ["median_points"]


def median_points(X1, X2, normal) -> np.ndarray:
    """Median points (M, 3) of a width whose sides' points are ``X1`` and ``X2``.

    Parameters
    ----------
    X1, X2 : (n1, 3), (n2, 3) float64
        The scan points of the two sides (each at least 3 points not on one line).
    normal : (3,)
        The width's direction (the segments' direction).

    Returns
    -------
    (M, 3): for each point of either side with an opposed point, the midpoint of the segment
    along ``normal`` between it and the other side (linear interpolation), in the same frame.

    Raises
    ------
    ValueError
        A side with fewer than 3 points, or no point with an opposed point.

    Example
    -------
    >>> import numpy as np
    >>> g = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2)
    >>> X1 = np.column_stack([g, np.full(25, 2.0)]); X2 = np.column_stack([g, np.zeros(25)])
    >>> float(np.ptp(median_points(X1, X2, [0, 0, 1])[:, 2]))
    0.0
    """
    from scipy.interpolate import LinearNDInterpolator

    X1, X2 = (np.asarray(x, np.float64) for x in (X1, X2))
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    if X1.ndim != 2 or X2.ndim != 2 or X1.shape[0] < 3 or X2.shape[0] < 3:
        raise ValueError(f"a median plane needs (n, 3) points on each side, n >= 3; got "
                         f"{X1.shape} and {X2.shape}")
    e1 = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    B = np.stack([e1, e2])
    out = []
    for A, O in ((X1, X2), (X2, X1)):
        uvA, uvO = A @ B.T, O @ B.T
        hO = LinearNDInterpolator(uvO, O @ n)(uvA)
        ok = np.isfinite(hO)
        h = 0.5 * (A[ok] @ n + hO[ok])
        out.append(uvA[ok] @ B + np.outer(h, n))
    M = np.concatenate(out)
    if len(M) == 0:
        raise ValueError("the two sides of the width do not overlap across its normal (no "
                         "point has an opposed point)")
    return M
