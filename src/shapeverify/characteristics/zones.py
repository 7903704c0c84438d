"""Tolerance zones on point sets: minimum-zone flatness, profile zone, ISO 14253-1 decisions.

Flatness (ISO 1101 §18.2, ISO 12781): the tolerance zone is the space between two parallel
planes a distance t apart; the measured flatness of a point set is the **minimum-zone** value:
the smallest distance between two parallel planes enclosing all points,

    F = min over unit n of ( max_i n . p_i  -  min_i n . p_i ),

i.e. the minimum width of the point set (the Chebyshev / minimax plane).  Computed by linear
programming: in a frame whose z axis is the current normal, ``min (c2 - c1)`` subject to
``c1 <= z_i - a x_i - b y_i <= c2`` (HiGHS); the normal is updated to ``(-a, -b, 1)`` and the
LP repeated until ``a = b = 0`` (to 1e-13): then the vertical width equals the orthogonal width
and no direction nearby gives a thinner slab (the first-order optimality conditions of the
orthogonal problem coincide with the LP's at ``a = b = 0``).  The result equals the brute-force
minimum over all candidate directions (normals of point triples and cross products of point-pair
differences) to rounding; tested.

Least-squares flatness (``least_squares_flatness``): range of the residuals about the total
least-squares plane (SVD) -- larger than or equal to the minimum-zone value.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

__all__ = ["minimum_zone_flatness", "least_squares_flatness", "decide", "worst_verdict",
           "VERDICTS", "is_one_sided", "zone_decide"]

#: ISO 14253-1 outcomes: conforms, does not conform, cannot be decided within the uncertainty
VERDICTS = ("pass", "fail", "undecided")


def _frame(n):
    n = np.asarray(n, np.float64) / np.linalg.norm(n)
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    x = np.cross(n, e)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


def least_squares_flatness(points) -> tuple[float, np.ndarray, np.ndarray]:
    """(range of residuals about the total least-squares plane, its normal (3,), centroid (3,))."""
    P = np.asarray(points, np.float64)
    c = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - c, full_matrices=False)
    r = (P - c) @ vt[2]
    return float(r.max() - r.min()), vt[2], c


def minimum_zone_flatness(points, normal=None, max_rounds: int = 20) -> tuple[float, np.ndarray]:
    """Minimum-zone flatness of points (N, 3), N >= 3 (see the module docstring).

    Parameters
    ----------
    points : (N, 3) float64
    normal : (3,), optional
        Start direction (default: the least-squares plane's normal).

    Returns
    -------
    width : float (mm);  normal : (3,) unit normal of the minimum-zone planes

    Raises
    ------
    ValueError
        Fewer than 3 points, non-finite values, or the LP solver failed.
    """
    P = np.asarray(points, np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 3:
        raise ValueError(f"flatness needs (N, 3) points with N >= 3, got shape {P.shape}")
    if not np.isfinite(P).all():
        raise ValueError("flatness points contain NaN/inf")
    c = P.mean(axis=0)
    Q = P - c
    n = least_squares_flatness(P)[1] if normal is None else np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    L = float(np.sqrt(np.mean(np.sum(Q * Q, axis=1)))) or 1.0
    H = Q
    if Q.shape[0] > 200:  # only the convex hull's vertices can touch the zone's planes
        try:
            from scipy.spatial import ConvexHull
            H = Q[ConvexHull(Q).vertices]
        except Exception:  # noqa: BLE001 - qhull on exactly coplanar points: use all of them
            H = Q
    m = H.shape[0]
    for _ in range(max_rounds):
        F = _frame(n)
        loc = H @ F
        x, y, z = loc[:, 0] / L, loc[:, 1] / L, loc[:, 2]
        # variables (a, b, c1, c2): minimise c2 - c1
        #   z - a x - b y <= c2  ->  -a x - b y - c2 <= -z
        #   z - a x - b y >= c1  ->   a x + b y + c1 <= z
        A = np.empty((2 * m, 4))
        A[:m, 0], A[:m, 1], A[:m, 2], A[:m, 3] = -x, -y, 0.0, -1.0
        A[m:, 0], A[m:, 1], A[m:, 2], A[m:, 3] = x, y, 1.0, 0.0
        bnd = np.r_[-z, z]
        res = linprog([0, 0, -1, 1], A_ub=A, b_ub=bnd, bounds=[(None, None)] * 4,
                      method="highs")
        if res.status != 0:
            raise ValueError(f"minimum-zone flatness: the LP failed ({res.message})")
        a, b = res.x[0] / L, res.x[1] / L
        step = np.hypot(a, b)
        n = F @ np.array([-a, -b, 1.0])
        n /= np.linalg.norm(n)
        if step < 1e-13:
            break
    d = Q @ n
    return float(d.max() - d.min()), n


def decide(value: float, lower: float | None, upper: float | None, U: float) -> str:
    """ISO 14253-1 decision with expanded uncertainty U (same unit as value).

    'pass' when ``lower + U <= value <= upper - U`` (inside the conformance zone), 'fail' when
    ``value < lower - U`` or ``value > upper + U``, otherwise 'undecided'.  A limit of None is
    not checked (one-sided characteristics: zone widths have only an upper limit).
    """
    if value is None or not np.isfinite(value):
        return "undecided"
    U = float(U) if np.isfinite(U) else np.inf
    if (upper is not None and value > upper + U) or (lower is not None and value < lower - U):
        return "fail"
    if (upper is None or value <= upper - U) and (lower is None or value >= lower + U):
        return "pass"
    return "undecided"


def worst_verdict(verdicts) -> str:
    """'fail' if any fails, else 'undecided' if any is undecided, else 'pass'."""
    v = list(verdicts)
    if "fail" in v:
        return "fail"
    if "undecided" in v or not v:
        return "undecided"
    return "pass"


def is_one_sided(type_name: str) -> bool:
    """The characteristic type's value is a zone width with an upper limit only
    (:mod:`.registry`'s ``one_sided``)."""
    from .registry import by_name

    return by_name(type_name).one_sided


def zone_decide(type_name: str, value: float, lower, upper, U: float) -> str:
    """:func:`decide` with the type's sidedness from the registry (a one-sided type's lower
    limit is not checked)."""
    return decide(value, None if is_one_sided(type_name) else lower, upper, U)
