"""Measuring a hole from scan points: centre from the edge points, diameter bias-corrected.

A scanner samples the sheet around a hole on a grid of spacing h and nothing inside it, so the
hole's edge is seen only through the innermost points.  Those *edge points* lie outside the true
edge by a fraction of a spacing (0 .. h, about h/2 on average: the half-spacing bias), so a circle
fitted to them is concentric with the hole but too large by about h/2 in radius.

:func:`measure_hole` therefore

1. works in the plane perpendicular to the nominal axis through the nominal centre (model frame,
   after alignment) and keeps the points of the sheet: within a few noise sigmas of a robust
   quadratic height fit over the ring ``r0/2 .. 2 r0 + 10 h`` (points seen *through* the hole, on
   other surfaces, are dropped);
2. takes as edge points the innermost point of each angular bin (bins one spacing of arc wide)
   and fits a circle to them (least squares).  The bias is radial, so it does not move the
   centre; the **centre** is the mean of that circle's centre and the centre of the largest
   circle holding no sheet point (the two err in partly independent ways: on simulated square
   and 1 x 1.4 grids the mean scatters 0.7-0.75 times as much as the edge circle alone);
3. corrects the **radius** by measuring, not assuming, the bias: the number of points within
   radius R of that centre is ``n(R) = rho (pi R^2 - A)`` for R outside the hole (rho the point
   density, A the hole's area); a linear least-squares fit of n(R) over R from
   ``r_edge + 2h`` to ``r_edge + 8h`` gives rho and A, and the radius is ``sqrt(A / pi)``
   (unbiased for any grid phase and any anisotropic spacing; on a square grid the edge points
   are 0.53 h outside the edge, on a 1 x 1.4 grid 0.79 h).  ``bias = r_edge - r`` is reported.

Uncertainties (standard, k = 1): the centre per in-plane axis ``0.75 s_edge sqrt(2 / n_edge)``
(``s_edge`` the RMS of the edge points about their circle, dominated by the grid quantisation);
the radius from 8 angular sectors measured the same way, ``std(r_k) / sqrt(8)``.  The
alignment's pose uncertainty is added by the caller.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..fitting import fit_circle

__all__ = ["HoleMeasurement", "measure_hole", "plane_basis"]

_SECTORS = 8


@dataclass(frozen=True, eq=False)
class HoleMeasurement:
    """A hole measured on the scan (model frame, mm; uncertainties standard, k = 1).

    center : (3,)  measured centre: the edge circle's centre, on the scanned sheet
    diameter : float   bias-corrected diameter
    edge_diameter : float  diameter of the circle through the edge points (uncorrected)
    bias : float   radial offset of the edge points outside the edge (mm)
    spacing : float  median point spacing around the hole (mm)
    n_edge : int   number of edge points
    u_center : float  standard uncertainty of each in-plane centre coordinate
    u_diameter : float  standard uncertainty of the diameter
    u_height : float  standard uncertainty of the centre along the axis
    edge_points : (n_edge, 3)
    """

    center: np.ndarray = field(repr=False)
    diameter: float
    edge_diameter: float
    bias: float
    spacing: float
    n_edge: int
    u_center: float
    u_diameter: float
    u_height: float
    edge_points: np.ndarray = field(repr=False)


def plane_basis(axis) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) completing ``axis`` to a right-handed orthonormal frame."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(a, e)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def _quad_design(xy: np.ndarray) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])


def _robust_height(xy, h, iterations: int = 6):
    A = _quad_design(xy)
    keep = np.ones(len(h), bool)
    coef = np.zeros(6)
    thr = np.inf
    for _ in range(iterations):
        coef, *_ = np.linalg.lstsq(A[keep], h[keep], rcond=None)
        res = h - A @ coef
        s = 1.4826 * np.median(np.abs(res[keep])) + 1e-6
        thr = 6.0 * s + 0.02
        new = np.abs(res) <= thr
        if np.array_equal(new, keep):
            break
        keep = new
    return coef, keep, thr


def _area_radius(rho: np.ndarray, r_edge: float, h: float, r_max: float):
    lo = r_edge + 2.0 * h
    hi = min(r_edge + 8.0 * h, r_max)
    if hi <= lo + 2 * h:
        return np.nan
    R = np.linspace(lo, hi, 13)
    n = np.searchsorted(np.sort(rho), R)
    A = np.column_stack([np.pi * R * R, -np.ones_like(R)])
    (dens, na), *_ = np.linalg.lstsq(A, n.astype(float), rcond=None)
    if not (dens > 0 and na > 0):
        return np.nan
    return float(np.sqrt(na / dens / np.pi))


def _largest_empty_circle(xy: np.ndarray, c0: np.ndarray, r: float, h: float) -> np.ndarray:
    """Centre (2,) of the largest circle near c0 that holds none of the points xy (n, 2)."""
    from scipy.optimize import minimize

    d0 = np.hypot(*(xy - c0).T)
    Q = xy[d0 < r + 3.0 * h]
    if Q.shape[0] < 3:
        return c0
    res = minimize(lambda c: -np.min(np.hypot(Q[:, 0] - c[0], Q[:, 1] - c[1])), c0,
                   method="Nelder-Mead", options={"xatol": 1e-7, "fatol": 1e-10,
                                                  "initial_simplex": c0 + 0.2 * h * np.array(
                                                      [[0, 0], [1, 0], [0, 1]])})
    c = res.x
    return c if np.linalg.norm(c - c0) < h else c0


def measure_hole(points, center, axis, diameter: float, spacing: float | None = None,
                 face=None, deviations=None, normals=None):
    """Measure one hole from scan points already in the model frame.

    Parameters
    ----------
    points : (N, 3) float64
        Scan points (model frame), at least those around the hole.
    center, axis : (3,)
        Nominal centre and axis of the hole (from :mod:`.features`).
    diameter : float
        Nominal diameter (mm).
    spacing : float, optional
        Scan point spacing (mm); default: the median nearest-neighbour distance near the hole.
    face : shapeverify.cad.model.Face, optional
        The CAD face of the hole.  With ``deviations`` and ``normals`` (the points' signed
        deviations and CAD normals, (N,) and (N, 3)) the centre's height along the axis is the
        CAD surface's there plus the mean deviation of the ring around the hole (exact for any
        surface shape); otherwise a quadratic fitted to the ring's heights.

    Returns
    -------
    HoleMeasurement

    Raises
    ------
    ValueError
        When too few sheet points surround the hole (not scanned, or shadowed): the message
        gives the counts.
    """
    P = np.asarray(points, np.float64)
    c0 = np.asarray(center, np.float64)
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    r0 = 0.5 * float(diameter)
    e1, e2 = plane_basis(a)
    q = P - c0
    xy = np.column_stack([q @ e1, q @ e2])
    hgt = q @ a
    rho = np.hypot(xy[:, 0], xy[:, 1])
    reach0 = 2.0 * r0 + 12.0 * (spacing or max(0.05 * r0, 0.5))
    near = (rho < reach0) & (np.abs(hgt) < max(r0, 5.0))
    ring = near & (rho > 0.5 * r0)
    if np.count_nonzero(ring) < 30:
        raise ValueError(f"only {int(np.count_nonzero(ring))} scan points around the hole at "
                         f"{np.round(c0, 3).tolist()} (diameter {diameter:.4g} mm); it is not "
                         "scanned, shadowed, or the alignment is off")
    coef, ok_ring, thr = _robust_height(xy[ring], hgt[ring])
    idx = np.flatnonzero(near)
    sheet = idx[np.abs(hgt[idx] - _quad_design(xy[idx]) @ coef) <= thr]
    if spacing is None:
        ann = sheet[(rho[sheet] > r0) & (rho[sheet] < r0 + max(5.0, 0.5 * r0))]
        if ann.size < 10:
            ann = sheet
        d, _ = cKDTree(xy[ann]).query(xy[ann], k=2)
        spacing = float(np.median(d[:, 1]))
    h = float(spacing)
    reach = 2.0 * r0 + 10.0 * h
    sheet = sheet[rho[sheet] < reach]
    # edge points: innermost point of each angular bin (bins ~ one spacing of arc)
    nb = max(12, int(round(2 * np.pi * r0 / h)))
    th = np.arctan2(xy[sheet, 1], xy[sheet, 0])
    b = np.floor((th + np.pi) / (2 * np.pi) * nb).astype(np.int64) % nb
    order = np.lexsort((rho[sheet], b))
    first = np.ones(order.size, bool)
    first[1:] = b[order][1:] != b[order][:-1]
    edge = sheet[order[first]]
    edge = edge[rho[edge] < r0 + 4.0 * h]
    if edge.size < 8:
        raise ValueError(f"only {edge.size} edge points found around the hole at "
                         f"{np.round(c0, 3).tolist()}; the hole is not scanned all round")
    circ = fit_circle(xy[edge])
    r_edge = float(circ.radius)
    s_edge = float(np.sqrt(np.mean(circ.residuals ** 2)))
    # centre: mean of the edge circle's and the largest empty circle's (see the module doc)
    cen2 = 0.5 * (circ.center + _largest_empty_circle(xy[sheet], circ.center, r_edge, h))
    rel = xy[sheet] - cen2
    rr = np.hypot(rel[:, 0], rel[:, 1])
    r_area = _area_radius(rr, r_edge, h, reach - np.linalg.norm(cen2))
    if not np.isfinite(r_area):
        raise ValueError(f"the sheet around the hole at {np.round(c0, 3).tolist()} is too "
                         "small to measure its diameter (needs about 8 point spacings all round)")
    ang = np.arctan2(rel[:, 1], rel[:, 0])
    sec = np.floor((ang + np.pi) / (2 * np.pi) * _SECTORS).astype(int) % _SECTORS
    rk = []
    for k in range(_SECTORS):
        rs = rr[sec == k]
        v = _area_radius(rs, r_edge, h, reach - np.linalg.norm(cen2))
        if np.isfinite(v):  # n_k(R) = (rho / 8)(pi R^2 - A): the same fit estimates r
            rk.append(v)
    u_r = float(np.std(rk, ddof=1) / np.sqrt(len(rk))) if len(rk) >= 3 else 0.5 * h
    res_h = hgt[sheet] - _quad_design(xy[sheet]) @ coef
    line = c0 + cen2[0] * e1 + cen2[1] * e2
    if face is not None and deviations is not None and normals is not None:
        from .features import hole_center_on_face

        ring = sheet[(rr > r_edge) & (rr < r_edge + 6.0 * h)]
        dv = np.asarray(deviations, np.float64)[ring]
        na = np.asarray(normals, np.float64)[ring] @ a
        shift = float(np.mean(dv / np.where(np.abs(na) > 0.2, na, 1.0)))
        c3 = hole_center_on_face(face, line, a) + shift * a
        u_h = float(np.std(dv) / np.sqrt(max(ring.size, 1)))
    else:
        hc = float(_quad_design(cen2[None])[0] @ coef)
        c3 = line + hc * a
        u_h = float(np.std(res_h) / np.sqrt(max(sheet.size, 1)) * np.sqrt(6.0))
    u_c = 0.75 * s_edge * np.sqrt(2.0 / edge.size)
    return HoleMeasurement(center=c3, diameter=2.0 * r_area, edge_diameter=2.0 * r_edge,
                           bias=r_edge - r_area, spacing=h, n_edge=int(edge.size),
                           u_center=float(u_c), u_diameter=2.0 * u_r, u_height=u_h,
                           edge_points=P[edge])
