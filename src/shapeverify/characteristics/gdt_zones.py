"""Minimum zones of the GD&T characteristics (ISO 1101, ISO 12780/12781/12181/12180), by
linear programming.

Every zone here is a *minimum zone* (Chebyshev) fit solved as a sequence of linear programmes
(HiGHS, :func:`scipy.optimize.linprog`) on the deviations linearised about the current
geometry, repeated until the update is below 1e-12 (then the linearisation is exact to second
order in the update, i.e. to rounding):

* :func:`planes_zone`: two parallel planes whose normal may turn only in the given directions
  (no direction: orientation fixed, e.g. parallelism to a datum plane; one: perpendicularity or
  angularity to a datum plane, the zone free to turn about the datum's normal; two: flatness).
  ``outer`` gives the constrained L-infinity plane on the material side (ISO 5459's datum plane,
  the outer plane of the minimum zone).
* :func:`circles_zone`: two concentric circles (circularity, ISO 12181), or, with
  ``kind="inscribed"``/``"circumscribed"``, the largest inscribed / smallest circumscribed circle
  (a hole's / boss's mating circle, ISO 5459's datum axis perpendicular to a datum plane).
* :func:`cylinders_zone`: two coaxial cylinders (cylindricity, ISO 12180), or the largest
  inscribed / smallest circumscribed cylinder (the mating size of a hole / boss).

Lengths in mm.  A solver failure raises ValueError naming the zone.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

__all__ = ["angular_coverage", "planes_zone", "width_planes", "circles_zone", "cylinders_zone", "tangent_basis"]

_ROUNDS = 60
_STOP = 1e-12


def tangent_basis(n) -> np.ndarray:
    """(2, 3) orthonormal vectors perpendicular to the unit vector n."""
    n = np.asarray(n, np.float64) / np.linalg.norm(n)
    e = np.eye(3)[int(np.argmin(np.abs(n)))]
    a = np.cross(n, e)
    a /= np.linalg.norm(a)
    return np.stack([a, np.cross(n, a)])


def _lp(c, A, b, what, step: float | None = None, n_step: int = 0):
    """HiGHS; the first ``n_step`` variables (the geometry's update) bounded by +-step (a trust
    region: a linearised problem of points on part of a circle may be unbounded)."""
    bounds = [(None, None)] * len(c)
    if step is not None:
        bounds[:n_step] = [(-step, step)] * n_step
    res = linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
    if res.status != 0:
        raise ValueError(f"minimum zone of {what}: the linear programme failed ({res.message})")
    return res.x


def _hull(Q):
    if Q.shape[0] <= 200:
        return Q
    try:
        from scipy.spatial import ConvexHull

        return Q[ConvexHull(Q).vertices]
    except Exception:  # noqa: BLE001 - coplanar/collinear points: all of them
        return Q


def planes_zone(points, normal, turn=(), outer: bool = False):
    """Two parallel planes enclosing the points, minimum distance apart.

    Parameters
    ----------
    points : (N, 3)
    normal : (3,)
        The zone's normal (start value; fixed when ``turn`` is empty).
    turn : sequence of (3,) vectors
        Directions in which the normal may turn (each perpendicular to ``normal``; 0, 1 or 2).
    outer : bool
        Also return the outer plane's offset (``max n.p``): with ``normal`` pointing out of
        the material that plane is the constrained L-infinity datum plane.

    Returns
    -------
    width : float, normal : (3,) unit, (lo, hi) : offsets ``min n.p``, ``max n.p``
    """
    P = np.asarray(points, np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 2:
        raise ValueError(f"a planes zone needs (N, 3) points, N >= 2; got {P.shape}")
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    c0 = P.mean(axis=0)
    H = _hull(P - c0)
    L = float(np.sqrt(np.mean(np.sum((P - c0) ** 2, axis=1)))) or 1.0
    turn = [np.asarray(t, np.float64) for t in turn]
    for _ in range(_ROUNDS if turn else 1):
        E = _turns_across(turn, n)
        if not E:
            break
        z = H @ n
        X = np.column_stack([H @ e for e in E]) / L
        m, k = H.shape[0], len(E)
        # variables (a_1..a_k, lo, hi): lo <= z - X a <= hi, minimise hi - lo
        A = np.block([[-X, np.zeros((m, 1)), -np.ones((m, 1))],
                      [X, np.ones((m, 1)), np.zeros((m, 1))]])
        x = _lp(np.r_[np.zeros(k), -1.0, 1.0], A, np.r_[-z, z], "parallel planes")
        a = x[:k] / L
        n = n - sum(ai * e for ai, e in zip(a, E))
        n /= np.linalg.norm(n)
        if np.abs(a).max() < _STOP:
            break
    d = P @ n
    return float(d.max() - d.min()), n, (float(d.min()), float(d.max()))


def _turns_across(turn, n) -> list:
    """The unit directions in which the normal ``n`` may turn: each of ``turn`` made
    perpendicular to ``n`` (one along ``n`` turns nothing and is left out)."""
    E = [t - (t @ n) * n for t in turn]
    return [e / np.linalg.norm(e) for e in E if np.linalg.norm(e) > 1e-9]


def width_planes(points1, points2, normal, turn=()):
    """The mating planes of a width (ISO 5459 / ASME Y14.5 actual mating envelope of two
    opposite planar faces), by LP.

    ``points1`` lie on the face whose outward normal is ``normal``, ``points2`` on the opposite
    face (outward normal ``-normal``).  Each plane has its face's points on the material side
    (``n.x <= h1`` on face 1, ``-n.x <= h2`` on face 2), and ``h1 + h2`` is minimal: for a tab
    the two closest planes enclosing it (its size ``h1 + h2``), for a slot the two farthest
    apart with no point inside (its size ``-(h1 + h2)``).  The normal turns only in ``turn``.

    Returns
    -------
    h1 + h2 : float, normal : (3,), (h1, h2), mid : float  (the centre plane ``n.x = mid``)
    """
    P1 = np.asarray(points1, np.float64)
    P2 = np.asarray(points2, np.float64)
    if P1.shape[0] < 1 or P2.shape[0] < 1:
        raise ValueError("a width needs points on both faces")
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    c0 = np.vstack([P1, P2]).mean(axis=0)
    H1, H2 = _hull(P1 - c0), _hull(P2 - c0)
    L = float(np.sqrt(np.mean(np.sum(np.vstack([H1, H2]) ** 2, axis=1)))) or 1.0
    turn = [np.asarray(t, np.float64) for t in turn]
    for _ in range(_ROUNDS if turn else 1):
        E = _turns_across(turn, n)
        if not E:
            break
        k = len(E)
        X1 = np.column_stack([H1 @ e for e in E]) / L
        X2 = np.column_stack([H2 @ e for e in E]) / L
        m1, m2 = H1.shape[0], H2.shape[0]
        # face 1: n.x - X a <= h1 ; face 2: -(n.x - X a) <= h2 ; vars (a, h1, h2)
        A = np.block([[-X1, -np.ones((m1, 1)), np.zeros((m1, 1))],
                      [X2, np.zeros((m2, 1)), -np.ones((m2, 1))]])
        b = np.r_[-(H1 @ n), H2 @ n]
        x = _lp(np.r_[np.zeros(k), 1.0, 1.0], A, b, "a width's mating planes")
        a = x[:k] / L
        n = n - sum(ai * e for ai, e in zip(a, E))
        n /= np.linalg.norm(n)
        if np.abs(a).max() < _STOP:
            break
    h1 = float((P1 @ n).max())
    h2 = float((-(P2 @ n)).max())
    return h1 + h2, n, (h1, h2), 0.5 * (h1 - h2)


def angular_coverage(points, point, axis) -> float:
    """Degrees of the circumference about the axis that the points cover (360 less the
    largest angular gap)."""
    B = tangent_basis(axis)
    q = (np.asarray(points, np.float64) - np.asarray(point, np.float64)) @ B.T
    if q.shape[0] < 2:
        return 0.0
    ang = np.sort(np.degrees(np.arctan2(q[:, 1], q[:, 0])))
    return 360.0 - float(np.diff(np.r_[ang, ang[0] + 360.0]).max())


#: a mating circle/cylinder needs points over this much of the circumference (degrees)
MIN_COVERAGE = 240.0


def _radial(xy, c):
    q = xy - c
    rho = np.sqrt(np.sum(q * q, axis=1))
    u = q / np.where(rho > 0, rho, 1.0)[:, None]
    return rho, u


def circles_zone(xy, center, kind: str = "zone"):
    """Circle fits of 2-D points by LP (see the module docstring).

    ``kind``: ``"zone"`` (two concentric circles, minimum radial separation), ``"inscribed"``
    (largest empty circle about the points' centre: all points outside it), ``"circumscribed"``
    (smallest circle holding all points).

    Returns
    -------
    value : float
        Zone width (r_out - r_in) for ``"zone"``, the radius otherwise.
    center : (2,)
    (r_in, r_out) : float
    """
    Q = np.asarray(xy, np.float64)
    if Q.ndim != 2 or Q.shape[1] != 2 or Q.shape[0] < 3:
        raise ValueError(f"a circle fit needs (N, 2) points, N >= 3; got {Q.shape}")
    c = np.asarray(center, np.float64).copy()
    m = Q.shape[0]
    tr = None
    for _ in range(_ROUNDS):
        rho, u = _radial(Q, c)
        tr = tr or 0.25 * float(rho.max())
        # radial distance after moving the centre by dc: rho - u.dc (first order)
        if kind == "zone":     # vars (dx, dy, lo, hi): lo <= rho - u dc <= hi
            A = np.block([[-u, np.zeros((m, 1)), -np.ones((m, 1))],
                          [u, np.ones((m, 1)), np.zeros((m, 1))]])
            x = _lp([0, 0, -1, 1], A, np.r_[-rho, rho], "concentric circles", tr, 2)
        elif kind == "inscribed":   # vars (dx, dy, r): max r, r <= rho - u dc
            A = np.column_stack([u, np.ones(m)])
            x = _lp([0, 0, -1], A, rho, "the inscribed circle", tr, 2)
        elif kind == "circumscribed":   # min r, rho - u dc <= r
            A = np.column_stack([-u, -np.ones(m)])
            x = _lp([0, 0, 1], A, -rho, "the circumscribed circle", tr, 2)
        else:
            raise ValueError(f"kind must be zone, inscribed or circumscribed, not {kind!r}")
        step = x[:2]
        c = c + step
        if np.linalg.norm(step) < _STOP * max(1.0, float(rho.max())):
            break
    rho, _ = _radial(Q, c)
    lo, hi = float(rho.min()), float(rho.max())
    value = hi - lo if kind == "zone" else (lo if kind == "inscribed" else hi)
    return value, c, (lo, hi)


def cylinders_zone(points, point, axis, kind: str = "zone"):
    """Cylinder fits of 3-D points by LP: axis through ``point`` along ``axis`` (start values).

    ``kind`` as in :func:`circles_zone` (``"zone"``: cylindricity; ``"inscribed"``: the hole's
    mating cylinder; ``"circumscribed"``: the boss's).

    Returns
    -------
    value : float, point : (3,), axis : (3,) unit, (r_in, r_out)
    """
    P = np.asarray(points, np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 5:
        raise ValueError(f"a cylinder fit needs (N, 3) points, N >= 5; got {P.shape}")
    p0 = np.asarray(point, np.float64).copy()
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    m = P.shape[0]
    L = None
    for _ in range(_ROUNDS):
        p0 = p0 + (((P.mean(axis=0) - p0) @ a) * a)   # axis point at the points' mid-height
        e1, e2 = tangent_basis(a)
        q = P - p0
        h = q @ a
        L = L or (float(np.abs(h).max()) or 1.0)
        xy = np.column_stack([q @ e1, q @ e2])
        rho, u = _radial(xy, np.zeros(2))
        tr = 0.25 * float(rho.max())
        # moving the axis by (d1, d2) at the mid-height and tilting it by (t1, t2) per unit height:
        # radial distance rho - u.(d + h t)
        J = np.column_stack([u, u * (h / L)[:, None]])
        if kind == "zone":
            A = np.block([[-J, np.zeros((m, 1)), -np.ones((m, 1))],
                          [J, np.ones((m, 1)), np.zeros((m, 1))]])
            x = _lp([0, 0, 0, 0, -1, 1], A, np.r_[-rho, rho], "coaxial cylinders", tr, 4)
        elif kind == "inscribed":
            x = _lp([0, 0, 0, 0, -1], np.column_stack([J, np.ones(m)]), rho,
                    "the inscribed cylinder", tr, 4)
        elif kind == "circumscribed":
            x = _lp([0, 0, 0, 0, 1], np.column_stack([-J, -np.ones(m)]), -rho,
                    "the circumscribed cylinder", tr, 4)
        else:
            raise ValueError(f"kind must be zone, inscribed or circumscribed, not {kind!r}")
        d = x[0] * e1 + x[1] * e2
        t = (x[2] * e1 + x[3] * e2) / L
        p0 = p0 + d
        a = a + t
        a /= np.linalg.norm(a)
        if max(np.linalg.norm(d), np.linalg.norm(t) * L) < _STOP * max(1.0, float(rho.max())):
            break
    q = P - p0
    r = np.linalg.norm(q - np.outer(q @ a, a), axis=1)
    lo, hi = float(r.min()), float(r.max())
    value = hi - lo if kind == "zone" else (lo if kind == "inscribed" else hi)
    return value, p0, a, (lo, hi)
