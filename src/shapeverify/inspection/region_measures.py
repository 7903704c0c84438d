"""A region's out-of-tolerance area and its extreme, measured so that the sampling does not show.

**Area.**  Each scan point near the region stands for its *cell*: its Voronoi cell among its
neighbours in its own tangent plane (:func:`._cluster_kernels.cell_areas`; the neighbours'
offsets are unfolded to their 3-D distance, so cells do not shrink across an edge), bounded by a
square of ``2 x CELL_BOUND`` spacings (a point in a gap stands for no more).  The cells of a
sampled surface tile it whatever the sampling -- random, a lattice, scanner rows, rows farther
apart than the points along them -- where a density from a few spacings around counts the
random clumping of a random sample (a dent of 25 points read -18 %).  Of each cell, the part
where ``g = |d| - |limit|`` (on the region's side) is positive counts: ``g`` is the point's own
value continued by the slope of a robust least-squares plane of ``g`` over its neighbours within
``SLOPE_RADIUS`` spacings (an in-tolerance point's over its in-tolerance neighbours only: across
a step the other side's points tilt the plane, and the crossing came to lie right beside the
in-tolerance point), so the boundary runs between an out-of-tolerance point and its
in-tolerance neighbours where ``g`` crosses zero, not half a cell beyond the last point out.
Where the scanned surface is steeper than 45 degrees to the CAD (the wall of an object lying on
the part: its points' feet crowd onto the rim's line) an out-of-tolerance point takes the slope
of the scan points' own plane (:func:`_steep_slopes`): a wall's is vertical, so the
boundary is its foot line, where the part's surface stops being in tolerance.  That plane is
the steep plane through the point that the most of its neighbours lie on (:func:`_wall_plane`;
else their principal plane): at a wall's top edge the object's top lies within reach too, and
a plane through both leaned the wall 20-60 degrees, putting the boundary a cell outside.
The region's area is the sum of these parts over its out-of-tolerance points and their
in-tolerance neighbours; a cell larger than ``2 x regions.SPARSE_AREA`` spacings^2 (a point in a gap
of the scan, beside the part) counts nothing.

**Extreme.**  A sampled dent's deepest point is missed by up to the spacing; the fitted peak of
the local surface is not.  A quadratic ``d(x, y)`` is fitted by least squares (3-sigma spike
rejection) to the deviations within ``r`` of a centre in its tangent plane, the centre is moved
to the fitted extremum and the fit repeated (at most ``PEAK_STEPS`` times).  ``r`` is a third of
the region's equivalent radius or half its half-width at the centre (a groove's), whichever is
less, at least ``MIN_PEAK_RADIUS`` spacings and enough for ``MIN_PEAK_POINTS`` points, at most
``MAX_PEAK_RADIUS`` spacings: a dent's top is a paraboloid only near its peak.  A valley or ridge
(one curvature only) has its extremum on its floor across it; a fit with no extremum in its
window is tried wider.  The stated uncertainty (one standard uncertainty) combines the fit's
standard error at the peak and its model error, a quarter of the change of the peak when the fit
reaches 1.5 times as far (the quartic term's bias grows fivefold).  The extreme never exceeds the
largest measured value by more than twice the fit's standard error, nor at all when the fit's
residuals exceed twice the local noise (``local_noise``: a flat-bottomed pit is no paraboloid):
then the data do not support the fit, and the largest measured value is the extreme (its
uncertainty the difference).
"""
from __future__ import annotations

import numpy as np
from shapeverify._lazy import cKDTree

from ..measures.spacing import nanmedian_rows, neighbour_noise
from ._cluster_kernels import cell_areas
from .region_folds import may_be_folded

__all__ = ["out_area", "fitted_peak", "seen_among", "on_a_wall", "CELL_BOUND", "SLOPE_RADIUS"]

#: A quadratic whose weaker curvature is under this share of its stronger one (or of the other
#: sign) is a valley or a ridge: its extremum is taken across it (``_stationary``).
VALLEY_FLAT = 0.2
#: Half size of the square that bounds a point's cell, in spacings.
CELL_BOUND = 1.5
#: A point whose neighbours within reach leave an empty sector wider than this (degrees) lies
#: at the edge of the scan: its neighbours mirrored through it bound its cell there.
EDGE_GAP = 150.0
#: Radius of the plane whose slope continues ``|d| - |limit|`` across a cell, in spacings.
SLOPE_RADIUS = 2.5
#: Radius (spacings, in space) of the scan points whose principal plane gives a steep surface's
#: slope, and the fewest points (with the point itself) it needs.
STEEP_RADIUS = 1.5
STEEP_MIN_POINTS = 5
#: Times the steep surface's plane is fitted again to the half of the points closest to it.
STEEP_TRIM = 2
#: ... and the points must spread across the plane at least this share of their spread along it.
STEEP_SPREAD = 0.25
#: ... and this many times their spread across it (a noisy row's plane is the noise's).
STEEP_DETERMINED = 3.0
#: ... and rise along the CAD normal with a standard deviation of at least this many times the
#: noise of the in-tolerance points around (a row of a scan as noisy as its spacing rises by
#: its noise).
STEEP_NOISE = 3.0
#: The wall's plane (:func:`_wall_plane`): its points within this many spacings in space, the
#: nearest ``WALL_K`` of them, candidate planes through the point and two of its ``WALL_PAIRS``
#: nearest (not within ``WALL_ANGLE`` (sine) of one line), a point on it within the larger of
#: ``WALL_NOISE`` x the noise and ``WALL_BAND`` spacings, and the fewest points on it.
WALL_RADIUS = 2.5
WALL_K = 24
WALL_PAIRS = 8
WALL_ANGLE = 0.3
WALL_NOISE = 3.0
WALL_BAND = 0.05
WALL_MIN_INLIERS = 5
#: ... and its slope to the CAD (a wall: a plane just steeper than 45 degrees holds a gentle
#: dent's points within a band of noise a quarter of the spacing wide, the wavy cube's at R/5).
WALL_SLOPE = 2.0
#: ... and its points' heights scatter about a quadratic along it by at least this share of
#: their spread (a patch, not a scanner row's curve across a dent: aniso rows on the wavy cube).
WALL_PATCH = 0.4
#: The peak's quadratic: smallest and largest radius (spacings), fewest points, most steps.
MIN_PEAK_RADIUS = 2.2
MAX_PEAK_RADIUS = 6.0
MIN_PEAK_POINTS = 15
PEAK_STEPS = 4
#: Smallest ratio of the quadratic's design matrix's singular values (coordinates in radii).
MIN_CONDITION = 0.02
#: The radius grows by this factor (at most ``GROW_STEPS`` times) until the points fix a quadratic.
GROW = 1.25
#: a wider window's fit is taken only when its residual sigma is at most ``GROW_FIT`` times the
#: first window's (or ``GROW_FIT_SHARE`` of the first value, for a noise-free first fit)
GROW_FIT = 3.0
GROW_FIT_SHARE = 0.1
GROW_STEPS = 4
#: Points whose cells are computed at once (memory: about 30 neighbours each).
CHUNK = 20000


def _basis(normals):
    n = normals / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    a = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return e1, np.cross(n, e1)


def out_area(tree, ev_idx, points, normals, g, q, spacing, values=None, above=True):
    """``(part, cell)`` (each (len(q),), mm^2): of each point ``q`` (scan indices of evaluated
    points), its cell's area and the part of it where ``g`` (per scan point, > 0 out of
    tolerance on the region's side) continued by its local slope is positive.

    ``tree`` holds the evaluated foot points ``points[ev_idx]`` (at least those within
    ``2 x CELL_BOUND`` spacings of ``q``).  ``values`` (per scan point, signed deviations along
    ``normals``; ``above``: the region's side, ``g`` rising with ``d`` or against it): the scan
    points ``points + values x normals`` give the out-of-tolerance points' slope where the
    scanned surface is steep to the CAD (:func:`_steep_slopes`)."""
    bound = CELL_BOUND * spacing
    reach = max(2.0 * bound, SLOPE_RADIUS * spacing)
    part = np.zeros(q.size)
    cell = np.zeros(q.size)
    noise = _noise_among(points, values, q[g[q] < 0]) if values is not None else 0.0
    for lo in range(0, q.size, CHUNK):
        qq = q[lo:lo + CHUNK]
        p = points[qq]
        nb = _neighbour_table(tree, ev_idx, p, reach)   # in scan order: independent of the tree
        ok = (nb >= 0) & (nb != qq[:, None])
        D = points[np.maximum(nb, 0)] - p[:, None, :]
        e1, e2 = _basis(normals[qq])
        x = np.einsum("ijk,ik->ij", D, e1)
        y = np.einsum("ijk,ik->ij", D, e2)
        r3 = np.linalg.norm(D, axis=2)
        rp = np.hypot(x, y)
        f = np.where(rp > 0, r3 / np.where(rp > 0, rp, 1.0), 1.0)   # unfolded to the 3-D distance
        x, y = np.where(ok, x * f, np.nan), np.where(ok, y * f, np.nan)
        g_nb = g[np.maximum(nb, 0)]
        # an in-tolerance point is continued by the slope of the in-tolerance surface around
        # it: across a step (the wall of an object lying on the part, 3 mm up) a plane through
        # the other side's points put the crossing right beside it, and the area grew by about
        # the perimeter times half a spacing on that side alone
        with np.errstate(invalid="ignore"):
            inside = ok & ((g_nb < 0) | (g[qq] >= 0)[:, None])
        gx, gy = _slopes(x, y, r3, inside, g_nb, g[qq], SLOPE_RADIUS * spacing)
        if values is not None:
            out = g[qq] >= 0
            if out.any():
                sg = 1.0 if above else -1.0          # g = d - limit, or -d - limit
                sx, sy = _steep_slopes(points, values, normals, nb[out], ok[out], qq[out],
                                       e1[out], e2[out], normals[qq[out]],
                                       sg * gx[out], sg * gy[out], STEEP_RADIUS * spacing,
                                       noise)
                gx[out], gy[out] = sg * sx, sg * sy
        x, y, nbc = _mirrored_at_scan_edge(x, y, nb)
        c = np.empty(qq.size)
        pa = np.empty(qq.size)
        cell_areas(np.ascontiguousarray(x), np.ascontiguousarray(y), nbc,
                   np.ascontiguousarray(qq, dtype=np.int64), np.ascontiguousarray(g[qq]),
                   gx, gy, float(bound), c, pa)
        part[lo:lo + qq.size] = pa
        cell[lo:lo + qq.size] = c
    return part, cell


def _mirrored_at_scan_edge(x, y, nb):
    """The neighbour offsets ``(x, y)`` (NaN: none) and indices ``nb`` with, for a point at the
    edge of the scan (its neighbours within reach leave an empty sector wider than
    ``EDGE_GAP`` degrees: the scanned area, or the part, stops there), its neighbours mirrored
    through it into that sector.  The cell of a point at the edge then reaches as far out as in,
    half a spacing on a lattice, where the bounding square let it reach ``CELL_BOUND`` spacings
    beyond the last points: a dent cut by the edge of the scanned area read +70 % at 1/5 of
    its radius.  Inside a scan such a sector is never empty (at the scan's density a random
    sample leaves one empty with probability about ``exp(-EDGE_GAP / 2 x 9)``)."""
    m, k = x.shape
    ang = np.where(np.isnan(x), np.inf, np.arctan2(y, x))
    a = np.sort(ang, axis=1)
    cnt = np.sum(np.isfinite(a), axis=1)
    edge = np.zeros(m, bool)
    lo = np.zeros(m)
    width = np.zeros(m)
    has = cnt >= 2
    if has.any():
        A = a[has]
        c = cnt[has]
        nxt = np.where(np.arange(k)[None, :] + 1 < c[:, None],
                       np.roll(A, -1, axis=1), A[:, :1] + 2 * np.pi)
        gaps = np.where(np.arange(k)[None, :] < c[:, None], nxt - A, -np.inf)
        j = np.argmax(gaps, axis=1)
        width[has] = gaps[np.arange(j.size), j]
        lo[has] = A[np.arange(j.size), j]
    edge = has & (width > np.radians(EDGE_GAP))
    if not edge.any():
        return x, y, nb
    mx, my = -x[edge], -y[edge]
    t = np.mod(np.arctan2(my, mx) - lo[edge][:, None], 2 * np.pi)
    inside = ~np.isnan(mx) & (t > 0) & (t < width[edge][:, None])
    X = np.full((m, k), np.nan)
    Y = np.full((m, k), np.nan)
    X[edge] = np.where(inside, mx, np.nan)
    Y[edge] = np.where(inside, my, np.nan)
    far = np.full((m, k), np.iinfo(np.int64).max, np.int64)   # never a coincident point
    return np.hstack([x, X]), np.hstack([y, Y]), np.hstack([nb, far])


def _noise_among(points, values, idx) -> float:
    """Noise sigma of the deviations ``values[idx]`` (in-tolerance points): ``1.4826 median
    |d_i - d_j| / sqrt 2`` over nearest foot-point neighbours (0 under 6 points)."""
    if idx.size < 6:
        return 0.0
    return neighbour_noise(points[idx], values[idx])


def _steep_slopes(points, values, normals, nb, ok, qq, e1, e2, n0, gx, gy, radius, noise=0.0):
    """Slope of ``d`` at the out-of-tolerance points ``qq``: the least-squares slope ``(gx,
    gy)`` of ``d``, or where the scanned surface is steeper than 45 degrees to the CAD the
    slope of its principal plane.

    The wall of an object lying on the part (a step) is sampled by points whose foot points
    crowd onto one line under it: the plane of ``d`` over the foot points is ill-posed there,
    and its slope (about the step's height over the neighbourhood) put the zero of ``g`` half a
    cell and more outside the wall, whose foot line *is* the boundary.  The orthogonal
    (principal-axis) plane of the scan points ``points + values x normals`` within ``radius``
    in space reads the wall as the step it is: its normal ``n`` in the point's frame gives the
    slope ``-(n1, n2) / n3`` of ``d``, pointing the way the least-squares plane rises (a
    vertical plane has two).  Where a steep plane through the point and two of its nearest
    holds enough of its neighbours (:func:`_wall_plane`) that plane is the wall's instead.  It
    is taken where that slope is steeper than 1 and than the least-squares one, so a gently
    sloping surface (a dent) keeps its least-squares slope."""
    S = points + values[:, None] * normals          # only rows of nb are read
    m, k = nb.shape
    j = np.maximum(nb, 0)
    D = S[j] - S[qq][:, None, :]
    with np.errstate(invalid="ignore"):
        near = ok & (np.linalg.norm(D, axis=2) <= radius)
    D = np.where(near[:, :, None], D, 0.0)          # padding and unevaluated rows: NaN
    X = np.einsum("ijk,ik->ij", D, e1)
    Y = np.einsum("ijk,ik->ij", D, e2)
    Z = np.einsum("ijk,ik->ij", D, n0)
    A = np.stack([X, Y, Z], axis=2)                 # (m, k, 3), the point itself at 0
    cnt = near.sum(axis=1) + 1.0
    W = near.astype(np.float64)
    # the plane through the point itself, fitted again to the half of its neighbours closest
    # to it (twice): at the top of a wall the object's top lies within the radius too, and a
    # plane through both leans 45 degrees
    for step in range(STEEP_TRIM + 1):
        C = np.einsum("ij,ijk,ijl->ikl", W, A, A)
        C = np.where((cnt >= STEEP_MIN_POINTS)[:, None, None], C, np.eye(3))
        lam, vec = np.linalg.eigh(C)
        n = vec[:, :, 0]                            # smallest principal axis
        if step == STEEP_TRIM:
            break
        r = np.where(near, np.abs(np.einsum("ijk,ik->ij", A, n)), np.nan)
        # the closer half, but never fewer than STEEP_MIN_POINTS - 1 (three points and the
        # point itself always fit a plane exactly)
        kth = np.sort(r, axis=1)[:, min(STEEP_MIN_POINTS - 2, r.shape[1] - 1)]
        with np.errstate(invalid="ignore"):
            cut = np.fmax(nanmedian_rows(r), kth)
            W = (near & (r <= cut[:, None])).astype(np.float64)
    ok_pca = (cnt >= STEEP_MIN_POINTS) & _fixes_a_wall(A, W, lam, noise)
    # the plane that the most points within WALL_RADIUS lie on (to the noise), of the steep
    # planes through the point and two of its nearest neighbours: at the top edge of a wall
    # the object's top lies within the radius too, and a principal plane through both (or
    # through the closer half of the few points at 1 mm spacing) leaned 20-45 degrees, so the
    # zero of g lay half a cell and more outside the wall's foot line
    spacing = radius / STEEP_RADIUS
    nw, ok_w = _wall_plane(S, nb, ok, qq, e1, e2, n0, WALL_RADIUS * spacing,
                           max(WALL_NOISE * noise, WALL_BAND * spacing), noise)
    n = np.where(ok_w[:, None], nw, n)
    t = np.hypot(n[:, 0], n[:, 1])
    slope = t / np.maximum(np.abs(n[:, 2]), t * 1e-6 + 1e-300)
    # d = -(n1 x + n2 y) / n3 on the plane: the slope's direction, its length capped
    along = -np.where(n[:, 2] < 0, -1.0, 1.0) * slope / np.maximum(t, 1e-300)
    sx, sy = n[:, 0] * along, n[:, 1] * along
    flip = sx * gx + sy * gy < 0
    sx, sy = np.where(flip, -sx, sx), np.where(flip, -sy, sy)
    steep = (ok_pca | ok_w) & (slope > 1.0) & (slope > np.hypot(gx, gy))
    return np.where(steep, sx, gx), np.where(steep, sy, gy)


def _fixes_a_wall(A, W, lam, noise):
    """Do the points ``A`` ((m, k, 3) in the point's frame, the CAD normal last) weighted by
    ``W``, whose plane's scatter matrix has eigenvalues ``lam`` (ascending), fix a steep plane?
    Points along one line (a scanner row) fix no plane: the plane's spread across its second
    axis must be a share of that along the first and several times that across it; and a
    steep surface rises along the CAD normal by more than the noise (a row of a scan as noisy
    as its spacing, whose plane holds the normal, rises by its noise alone)."""
    Z = A[:, :, 2]
    nk = W.sum(axis=1)
    zm = (W * Z).sum(axis=1) / np.maximum(nk, 1.0)
    zsd = np.sqrt(np.maximum((W * (Z - zm[:, None]) ** 2).sum(axis=1) / np.maximum(nk, 1.0), 0.0))
    return (lam[:, 1] >= STEEP_SPREAD ** 2 * lam[:, 2]) & \
        (lam[:, 1] >= STEEP_DETERMINED ** 2 * np.maximum(lam[:, 0], 0.0)) & \
        (zsd >= STEEP_NOISE * noise)


def _wall_plane(S, nb, ok, qq, e1, e2, n0, radius, band, noise):
    """``(normal (m, 3) in each point's frame, found (m,))``: the steep plane (slope > ``WALL_SLOPE`` to the
    CAD) through each point ``qq`` and two of its ``WALL_PAIRS`` nearest scan points ``S`` in
    space that the most of its ``WALL_K`` nearest within ``radius`` lie on (within ``band``),
    refitted to those points; found when at least ``WALL_MIN_INLIERS`` lie on it and they fix
    a plane (:func:`_fixes_a_wall`).  A wall's top-edge point lies on two planes, the wall's
    and the object's top: the steep one is the wall's, down which ``g`` falls to the limit."""
    m = qq.size
    j = np.maximum(nb, 0)
    D = S[j] - S[qq][:, None, :]
    A = np.stack([np.einsum("ijk,ik->ij", D, e) for e in (e1, e2, n0)], axis=2)
    r = np.linalg.norm(A, axis=2)
    with np.errstate(invalid="ignore"):
        near = ok & (r <= radius) & (r > 0)
    r = np.where(near, r, np.inf)
    k = min(WALL_K, r.shape[1])
    o = np.argsort(r, axis=1, kind="stable")[:, :k]
    B = np.take_along_axis(A, o[:, :, None], axis=1)
    Bv = np.isfinite(np.take_along_axis(r, o, axis=1))
    B = np.where(Bv[:, :, None], B, 0.0)
    p = min(WALL_PAIRS, k)
    ia, ib = np.triu_indices(p, 1)
    if ia.size == 0 or m == 0:
        return np.zeros((m, 3)), np.zeros(m, bool)
    Ca = np.cross(B[:, ia], B[:, ib])                        # (m, pairs, 3)
    la = np.linalg.norm(Ca, axis=2)
    lab = np.linalg.norm(B[:, ia], axis=2) * np.linalg.norm(B[:, ib], axis=2)
    Nc = Ca / np.maximum(la, 1e-300)[:, :, None]
    good = Bv[:, ia] & Bv[:, ib] & (la >= WALL_ANGLE * lab) & \
        (np.hypot(Nc[:, :, 0], Nc[:, :, 1]) > WALL_SLOPE * np.abs(Nc[:, :, 2]))
    res = np.abs(np.einsum("ikj,icj->ick", B, Nc))            # (m, pairs, k)
    inl = (res <= band) & Bv[:, None, :]
    count = np.where(good, inl.sum(axis=2), -1)
    best = np.argmax(count, axis=1)
    W = np.take_along_axis(inl, best[:, None, None], axis=1)[:, 0].astype(np.float64)
    found = np.take_along_axis(count, best[:, None], axis=1)[:, 0] >= WALL_MIN_INLIERS
    C = np.einsum("ij,ijk,ijl->ikl", W, B, B)
    C = np.where(found[:, None, None], C, np.eye(3))
    lam, vec = np.linalg.eigh(C)
    n = vec[:, :, 0]
    found &= _fixes_a_wall(B, W, lam, noise) & \
        (np.hypot(n[:, 0], n[:, 1]) > WALL_SLOPE * np.abs(n[:, 2]))
    # a wall is a patch: its points' heights are no function of where they lie along it (a
    # scanner row across a curved dent lies in a steep plane too, as a curve z(t))
    h = np.stack([-n[:, 1], n[:, 0], np.zeros(m)], axis=1)
    h /= np.maximum(np.linalg.norm(h, axis=1), 1e-300)[:, None]
    t = np.einsum("ijk,ik->ij", B, h)
    Z = B[:, :, 2]
    X = np.stack([np.ones_like(t), t, t * t], axis=2)            # the point itself: (1, 0, 0)
    M = np.einsum("ij,ijk,ijl->ikl", W, X, X)
    M[:, 0, 0] += 1.0
    M = np.where(found[:, None, None], M, np.eye(3))
    c = np.linalg.solve(M + 1e-12 * np.eye(3), np.einsum("ij,ijk,ij->ik", W, X, Z)[:, :, None])[:, :, 0]
    res = (W * (Z - np.einsum("ijk,ik->ij", X, c)) ** 2).sum(axis=1) + c[:, 0] ** 2
    nk = W.sum(axis=1) + 1.0
    rz = np.sqrt(res / np.maximum(nk - 3.0, 1.0))
    zm = (W * Z).sum(axis=1) / nk
    zsd = np.sqrt(((W * (Z - zm[:, None]) ** 2).sum(axis=1) + zm ** 2) / nk)
    found &= rz >= WALL_PATCH * zsd
    return n, found


def on_a_wall(X, normals, spacing) -> np.ndarray:
    """(n,) bool: the points ``X`` (in space, CAD ``normals``) that lie on a wall among
    themselves: a steep plane through the point and two of its nearest holding enough of its
    ``WALL_K`` nearest within ``WALL_RADIUS`` spacings, as a patch (:func:`_wall_plane`; band
    ``2 x WALL_BAND`` spacings, the noise unknown).  At 1 mm the walls of a 3 mm object beyond
    the evaluation distance are two spacings tall: the plane of a point's 8 nearest
    (:func:`.regions.steep_points`) holds the object's top too, and three quarters of the
    walls read as surface lying over the part's (the box on a lattice scan: the part passed)."""
    n = X.shape[0]
    if n < WALL_MIN_INLIERS + 1:
        return np.zeros(n, bool)
    k = min(WALL_K + 1, n)
    d, j = cKDTree(X).query(X, k=k, distance_upper_bound=WALL_RADIUS * spacing)
    d, j = d.reshape(n, k)[:, 1:], j.reshape(n, k)[:, 1:]
    ok = np.isfinite(d)
    nb = np.where(ok, j, -1).astype(np.int64)
    e1, e2 = _basis(normals)
    nn = normals / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    _, found = _wall_plane(X, nb, ok, np.arange(n), e1, e2, nn, WALL_RADIUS * spacing,
                           2.0 * WALL_BAND * spacing, 0.0)
    return found


def _neighbour_table(tree, ev_idx, p, radius):
    """(len(p), k) int64: the scan indices ``ev_idx[j]`` of the tree's points within ``radius``
    of each row of ``p``, ascending along each row, padded with -1 (k: the most found, at least 1).

    One padded k-nearest query (the same points as ``query_ball_point``: distance <= radius)
    sorted by row: no Python lists of neighbours."""
    lens = tree.query_ball_point(p, radius, return_length=True)
    k = max(1, int(np.max(lens, initial=0)))
    nb = np.full((p.shape[0], k), -1, np.int64)
    if p.shape[0] == 0 or int(np.sum(lens)) == 0:
        return nb
    d, j = tree.query(p, k=k, distance_upper_bound=np.nextafter(radius, np.inf))
    d, j = d.reshape(p.shape[0], k), j.reshape(p.shape[0], k)
    big = np.iinfo(np.int64).max
    v = np.where(d <= radius, ev_idx[np.minimum(j, ev_idx.size - 1)], big)
    v.sort(axis=1)
    return np.where(v == big, -1, v)


def _slopes(x, y, r3, ok, g_nb, g0, radius):
    """Slope ``(gx, gy)`` of a least-squares plane of ``g`` over each point and its neighbours
    within ``radius``; neighbours beyond 3 robust sigmas of the first plane are dropped (one
    spike among them tilts a plane); 0 where the plane is undetermined."""
    w = ok & (r3 <= radius)
    m = x.shape[0]
    X = np.column_stack([np.zeros(m), np.where(w, x, 0.0)])
    Y = np.column_stack([np.zeros(m), np.where(w, y, 0.0)])
    G = np.column_stack([g0, np.where(w, g_nb, 0.0)])
    W = np.column_stack([np.ones(m, bool), w]).astype(np.float64)
    gx = np.zeros(m)
    gy = np.zeros(m)
    for step in range(2):
        S = W.sum(1)
        sx, sy, sg = (W * X).sum(1), (W * Y).sum(1), (W * G).sum(1)
        sxx, sxy, syy = (W * X * X).sum(1), (W * X * Y).sum(1), (W * Y * Y).sum(1)
        sxg, syg = (W * X * G).sum(1), (W * Y * G).sum(1)
        M = np.stack([np.stack([S, sx, sy], -1), np.stack([sx, sxx, sxy], -1),
                      np.stack([sy, sxy, syy], -1)], -2)
        rhs = np.stack([sg, sxg, syg], -1)
        det = np.linalg.det(M)
        scale = np.maximum(S * sxx * syy, 1e-300)
        good = (S >= 4) & (np.abs(det) > 1e-9 * scale)
        sol = np.zeros((m, 3))
        if good.any():
            sol[good] = np.linalg.solve(M[good], rhs[good][:, :, None])[:, :, 0]
        gx = np.where(good, sol[:, 1], 0.0)
        gy = np.where(good, sol[:, 2], 0.0)
        if step == 1:
            break
        res = G - (sol[:, :1] + sol[:, 1:2] * X + sol[:, 2:3] * Y)
        r = np.where(W > 0, np.abs(res), np.nan)
        sig = 1.4826 * nanmedian_rows(r)
        keep = (W > 0) & (np.abs(res) <= 3.0 * sig[:, None] + 1e-12 * (np.abs(G).max() + 1.0))
        keep[:, 0] = True                                # the point itself stays
        W = keep.astype(np.float64)
    return gx, gy


def _fit(center, e1, e2, tree, ev_idx, points, values, radius):
    """Robust least-squares quadratic of the deviations within ``radius`` of ``center``:
    ``(coefficients, (A^T A)^-1, residual sigma, points kept)`` or None (under 12 points)."""
    nb = np.sort(ev_idx[tree.query_ball_point(center, radius)])
    if nb.size < 12:
        return None
    d = points[nb] - center
    x, y = d @ e1 / radius, d @ e2 / radius        # scaled: the conditioning below is unitless
    A = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
    sv = np.linalg.svd(A, compute_uv=False)
    if not sv[-1] > MIN_CONDITION * sv[0]:
        return None           # the points do not fix a quadratic (e.g. two scanner rows)
    b = values[nb]
    keep = np.ones(b.size, bool)
    for _ in range(3):                     # drop spikes: residuals beyond 3 robust sigmas
        c, *_ = np.linalg.lstsq(A[keep], b[keep], rcond=None)
        res = b - A @ c
        scale = 1.4826 * np.median(np.abs(res[keep])) + 1e-12 * (abs(c[0]) + 1e-300)
        new = np.abs(res) <= 3.0 * scale
        if new.sum() < 12 or np.array_equal(new, keep):
            break
        keep = new
    Ak = A[keep]
    n_k = int(keep.sum())
    sigma = float(np.sqrt(np.sum(res[keep] ** 2) / max(n_k - 6, 1)))
    try:
        cov = np.linalg.inv(Ak.T @ Ak)
    except np.linalg.LinAlgError:
        return None
    # back to mm: d = c0 + c1 x/r + ... + c5 (y/r)^2
    unscale = np.array([1.0, 1 / radius, 1 / radius, radius ** -2, radius ** -2, radius ** -2])
    return c * unscale, cov * np.outer(unscale, unscale), sigma, n_k


def _stationary(c, radius):
    """The extremum ``(x, y)`` of the quadratic ``c`` when it is one of the sign of ``c[0]``
    (a dent's minimum, a bump's maximum) within ``radius``; else None.

    A groove or a ridge (one curvature of that sign, the other ``VALLEY_FLAT`` times weaker or
    of the other sign: the floor runs on along the groove) has its extremum across it: the
    point of the valley's floor nearest the centre.  (Its value at the fit's centre, a core
    point up to a spacing off the floor, read a groove 3-10 % shallow at 1/5 of its half-width.)"""
    H = np.array([[2 * c[3], c[4]], [c[4], 2 * c[5]]])
    sign = -np.sign(c[0])                       # the curvature of an extremum on c's side
    if np.linalg.det(H) > 0 and np.sign(H[0, 0]) == sign:
        s = np.linalg.solve(H, -c[1:3])
        if np.hypot(*s) <= radius:
            return s
    lam, vec = np.linalg.eigh(H)
    k = int(np.argmax(sign * lam))
    other = lam[1 - k]
    if not (sign * lam[k] > 0 and sign * other < VALLEY_FLAT * sign * lam[k]):
        return None
    v = vec[:, k]
    s = -(v @ c[1:3]) / lam[k] * v
    return s if np.hypot(*s) <= radius else None


def _value(c, cov, sigma, s):
    a = np.array([1.0, s[0], s[1], s[0] ** 2, s[0] * s[1], s[1] ** 2])
    return float(a @ c), float(sigma * np.sqrt(max(a @ cov @ a, 0.0)))


def _peak_at(center, normal, tree, ev_idx, points, values, radius):
    """``(value, se, position, sigma, found)`` of the fitted extremum moved to from ``center``
    (or, ``found`` False, the fit's value at its last centre when it has none), or None."""
    n = normal / (np.linalg.norm(normal) or 1.0)
    e1, e2 = _basis(n[None])
    e1, e2 = e1[0], e2[0]
    at = np.asarray(center, np.float64).copy()
    best = None
    for _ in range(PEAK_STEPS):
        fit = _fit(at, e1, e2, tree, ev_idx, points, values, radius)
        if fit is None:
            break
        c, cov, sigma, _ = fit
        s = _stationary(c, radius)
        if s is None:
            v, se = _value(c, cov, sigma, np.zeros(2))
            best = (v, se, at.copy(), sigma, False)
            break
        v, se = _value(c, cov, sigma, s)
        best = (v, se, at + s[0] * e1 + s[1] * e2, sigma, True)
        if np.hypot(*s) <= 0.05 * radius:
            break
        at = best[2]
    return best


def fitted_peak(center, normal, tree, ev_idx, points, values, spacing, area, half_width=None):
    """``(extreme, uncertainty, position, standard error of the fit alone, its residual sigma)``
    of a region
    (module docstring), or None when there are too few points around ``center`` for a
    quadratic."""
    size = np.sqrt(area / np.pi) / 3.0
    if half_width is not None:
        # a groove's half-width, far under its equivalent radius (a third of that spanned its
        # whole profile); half of it: a third held too few points at 1/15 of the half-width,
        # and the worst of many noisy fits along the floor read +2..+7.5 %
        size = min(size, half_width / 2.0)
    r = float(np.clip(size, MIN_PEAK_RADIUS * spacing,
                      MAX_PEAK_RADIUS * spacing))
    k = min(MIN_PEAK_POINTS, ev_idx.size)
    d, _ = tree.query(center, k=k)
    d = np.atleast_1d(d)
    if np.isfinite(d[-1]):
        r = max(r, float(d[-1]) * (1 + 1e-9))
    first = None
    for _ in range(GROW_STEPS + 1):
        fit = _peak_at(center, normal, tree, ev_idx, points, values, r)
        # a wider window's fit must fit as the first did (a box 3 mm tall on the panel, lattice
        # at 1 mm: the first window on its flat top had no extremum, sigma 0.02; the wider one
        # took in the walls, sigma 0.85, and peaked at 3.61)
        if fit is not None and (first is None or (
                fit[4] and abs(fit[0]) > abs(first[0])
                and fit[3] <= max(GROW_FIT * first[3], GROW_FIT_SHARE * abs(first[0])))):
            first, r_first = fit, r
        # a quadratic with no extremum in its window is no peak of the data (a random scan at
        # 1/5 of a dent's radius, its centre between points: the fit from a core point 4.7 mm
        # off the centre was a saddle, its value there -0.393 for a 0.5 mm dent whose points
        # measured down to -0.472): a wider window is tried, and its peak taken when it lies
        # beyond that value (on a box's flat top the wider window took in the walls and
        # peaked at 1.89 for 3 mm: no peak of the data either)
        if (first is not None and first[4]) or r * GROW > MAX_PEAK_RADIUS * spacing:
            break
        r *= GROW
    if first is None:
        return None
    r = r_first
    wide = _peak_at(first[2], normal, tree, ev_idx, points, values, 1.5 * r)
    model = abs(first[0] - wide[0]) / 4.0 if wide is not None else 0.0
    return first[0], float(np.hypot(first[1], model)), first[2], float(first[1]), float(first[3])


def local_noise(tree, ev_idx, values, center, radius) -> float:
    """Noise sigma of the deviations around ``center`` (mm): ``1.4826 median |d_i - d_j| /
    sqrt 2`` over nearest-neighbour pairs within ``radius`` (the form cancels in a neighbour's
    difference; a step between a few pairs does not move the median).  NaN under 6 points."""
    i = np.sort(np.asarray(tree.query_ball_point(center, radius), np.int64))
    if i.size < 6:
        return float("nan")
    return neighbour_noise(tree.data[i], values[ev_idx[i]])


#: The in-tolerance surface seen at a point: it lies in a Delaunay triangle of the deep-in-tolerance
#: points whose circumradius is at most ``SEEN_ALPHA`` of their spacing (an alpha shape).
SEEN_ALPHA = 1.25
#: ... their spacing taken at most this many times the scan's (the two sides of a thin wall halve
#: the area per point the scan's spacing is measured as).
SEEN_SPARSEST = np.sqrt(2.0)
#: Most core points of a component tested; the window around them, in spacings.
SEEN_SAMPLE = 64
SEEN_WINDOW = 4.0


def _dot(a, v):
    """``a @ v`` for (n, 3) ``a`` and (3,) ``v``, without BLAS."""
    return a[:, 0] * v[0] + a[:, 1] * v[1] + a[:, 2] * v[2]


def _containing(P, simplices, X):
    """Index of a triangle ``P[simplices]`` that holds each point ``X`` (2-D), -1 for none: by
    the signs of the three edge functions (``Delaunay.find_simplex`` computes LAPACK transforms
    of every triangle, and OpenBLAS's threads spin after them)."""
    a, b, c = P[simplices[:, 0]], P[simplices[:, 1]], P[simplices[:, 2]]

    def edge(u, v):
        return ((v[:, 0] - u[:, 0])[None] * (X[:, 1:2] - u[:, 1][None])
                - (v[:, 1] - u[:, 1])[None] * (X[:, 0:1] - u[:, 0][None]))

    e = np.stack([edge(a, b), edge(b, c), edge(c, a)])
    tol = 1e-12 * float(np.ptp(P, axis=0).max()) ** 2      # a point on an edge is in both
    inside = np.all(e >= -tol, axis=0) | np.all(e <= tol, axis=0)
    return np.where(inside.any(axis=1), np.argmax(inside, axis=1), -1)


def _circumradii(P, simplices):
    a, b, c = P[simplices[:, 0]], P[simplices[:, 1]], P[simplices[:, 2]]
    la = np.linalg.norm(b - c, axis=1)
    lb = np.linalg.norm(a - c, axis=1)
    lc = np.linalg.norm(a - b, axis=1)
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                        - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    return la * lb * lc / np.maximum(4.0 * area, 1e-300), area


def seen_under(tree, ev_idx, values, normals, points, core, above, lo_lim, hi_lim,
               spacing) -> float:
    """Share of the core points ``core`` (scan indices of one component, all on one side:
    ``above``) that are out of tolerance and under or over which the part's in-tolerance
    surface is seen.

    The surface seen is the alpha shape of the evaluated points deep inside the tolerance
    (``|d|`` at most half the limit on the component's side) on the same side of the part
    (normal within 60 degrees of the component's), in the tangent plane of the component: the
    Delaunay triangles whose circumradius is at most ``SEEN_ALPHA`` times the spacing of those
    points (``sqrt(2 x`` their mean triangle area``)``, triangles of up to twice the median
    circumradius; so the test holds for random, lattice, row and doubled sampling and on thin
    walls, whose two sides halve the scan's area per point), that spacing at most
    ``SEEN_SPARSEST`` times the scan's.  A real defect replaces the
    surface: inside it the triangles span the hole (a pit 2 spacings across: a circumradius of
    about 2 spacings), and only points within a fraction of a spacing of its rim are covered;
    a scratch 2 spacings wide, about 1.4 spacings.  A reflection or a ghost lying over good
    surface, however sparse, has the surface's ordinary triangles around each of its points.
    At most ``SEEN_SAMPLE`` core points are tested (evenly spread over their order).
    """
    from scipy.spatial import Delaunay, QhullError

    core = np.asarray(core)
    # its own out-of-tolerance points (a core point in tolerance is measured surface itself)
    core = core[values[core] > hi_lim[core]] if above else core[values[core] < lo_lim[core]]
    if core.size == 0:
        return 0.0
    sample = core[np.linspace(0, core.size - 1, min(core.size, SEEN_SAMPLE)).astype(np.int64)]
    n = normals[sample].sum(axis=0)
    if not np.linalg.norm(n) > 0:
        return 0.0
    n = n / np.linalg.norm(n)
    lists = tree.query_ball_point(points[sample], SEEN_WINDOW * spacing)
    w = np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists]))
    gi = ev_idx[w]
    lim = np.abs(hi_lim[gi] if above else lo_lim[gi])
    # (sums of products, not a BLAS product: OpenBLAS threads for a few thousand rows and spins)
    deep = gi[(np.abs(values[gi]) <= 0.5 * lim) & (_dot(normals[gi], n) > 0.5)]
    if deep.size >= 8:
        # nor points that may be another face's pushed beyond the limit (a dent on a convex
        # edge: :func:`.region_folds.behind_other_face`)
        deep = deep[~may_be_folded(tree, ev_idx, values, normals, points, deep,
                                   (hi_lim if above else lo_lim,), spacing)[0]]
    if deep.size < 8:
        return 0.0
    e1, e2 = _basis(n[None])
    centre = points[sample].mean(axis=0)
    Q = points[deep] - centre
    Q2 = np.column_stack([_dot(Q, e1[0]), _dot(Q, e2[0])])
    try:
        tri = Delaunay(Q2)
    except (QhullError, ValueError):
        return 0.0                                   # all on a line: no surface around
    R, area = _circumradii(Q2, tri.simplices)
    ordinary = R <= 2.0 * np.median(R)
    # their spacing, but no sparser than a surface sampled at the scan's density (both sides of a
    # thin wall count in ``spacing``): points inside a shallow dent that noise brings deep into
    # the tolerance are no surface
    s_deep = min(np.sqrt(2.0 * area[ordinary].mean()), SEEN_SPARSEST * spacing)
    X = points[sample] - centre
    at = _containing(Q2, tri.simplices, np.column_stack([_dot(X, e1[0]), _dot(X, e2[0])]))
    covered = (at >= 0) & (R[np.maximum(at, 0)] <= SEEN_ALPHA * s_deep)
    return float(np.mean(covered))


#: The surface is seen around a point when its ``SEEN_K``-th nearest deep-in-tolerance point (of
#: the same side of the part) is no farther than the ``SEEN_QUANTILE`` quantile of that distance
#: among the deep points themselves.
SEEN_K = 3
SEEN_QUANTILE = 0.75
#: Normals within this cosine count as the same side of the part (60 degrees).
SEEN_SAME_SIDE = 0.5
#: The reference distances are those of the deep points between ``SEEN_INNER`` and
#: ``SEEN_WINDOW`` spacings from the component's points; their neighbours are looked for
#: ``SEEN_REACH`` spacings farther.
SEEN_INNER = 2.0
SEEN_REACH = 1.5
#: Most reference points (evenly spread over their order), and fewest.
SEEN_RING = 256
SEEN_MIN_RING = 16
#: The reference surface is taken no sparser than this many times the scan's spacing: a guard
#: against a reference of a few scattered points (the normal case reads 1-1.4 x the scan's
#: spacing: a thin wall's two sides halve the area per point the spacing is measured as, and a
#: random sample's local density varies; a degenerate one 3 x or more).
SEEN_RING_SPARSEST = 2.0


def _poisson_kth(k, q) -> float:
    """The ``q`` quantile of the distance to the ``k``-th nearest point of a random (Poisson)
    sample of one point per unit area (``pi r^2`` is Gamma(k) distributed)."""
    from scipy.special import gammaincinv

    return float(np.sqrt(gammaincinv(k, q) / np.pi))


def _kth_same_side(dtree, deep_n, p, p_n, k, skip_self):
    """Distance from each ``p`` to its ``k``-th nearest point of ``dtree`` whose normal
    ``deep_n`` is within 60 degrees of ``p_n`` (inf when there are fewer)."""
    kk = min(dtree.n, 4 * k + 4 + int(skip_self))
    d, j = dtree.query(p, k=kk)
    d, j = d.reshape(len(p), kk), j.reshape(len(p), kk)
    jj = np.minimum(j, dtree.n - 1)
    ok = np.isfinite(d) & (np.einsum("ijk,ik->ij", deep_n[jj], p_n) > SEEN_SAME_SIDE)
    if skip_self:
        ok[:, 0] = False                                  # the point itself (distance 0)
    rank = np.cumsum(ok, axis=1)
    hit = ok & (rank == k)
    return np.where(hit.any(axis=1), d[np.arange(len(p)), np.argmax(hit, axis=1)], np.inf)


def seen_around(tree, ev_idx, values, normals, points, members, above, lo_lim, hi_lim,
                spacing) -> float:
    """Share of a component's out-of-tolerance points ``members`` (scan indices, all on one
    side: ``above``) among which the part's in-tolerance surface is measured as densely as it is
    among its own points.

    A reflection, ghost or misplaced second view lies over good surface: the surface is sampled
    *under* it, independently of where the layer's points fall, so the distance from a layer
    point to its ``SEEN_K``-th nearest deep-in-tolerance point (``|d|`` at most half the limit;
    on the same side of the part: normal within 60 degrees of the point's own, which keeps the
    test on a curved face, at an edge and on both sides of a thin blade) is distributed like
    that distance among the deep points themselves (for a random sample exactly so): about
    ``SEEN_QUANTILE`` of the layer's points are within that quantile of it.  A real defect
    replaces the surface: the deep points lie beyond its rim and the band where ``|d|`` climbs
    from half the limit to the limit, so a point inside it is farther from its ``SEEN_K``-th
    deep point than a deep point is (a point at a rim of random samples sees a half plane: about
    0.3 of them are within the quantile, the interior none).  The reference is the local
    sampling itself (any density, random, lattice or rows, a doubled exposure): no spacing is
    assumed.  The test takes the component's out-of-tolerance points, not its core points: a
    layer point close to the surface's own points has an in-tolerance neighbourhood median, so
    the core points of a layer are those in the surface's sampling holes.  At most
    ``SEEN_SAMPLE`` points are tested (evenly spread over their order).
    """
    members = np.asarray(members)
    members = members[values[members] > hi_lim[members]] if above else \
        members[values[members] < lo_lim[members]]
    if members.size == 0:
        return 0.0
    sample = members[np.linspace(0, members.size - 1,
                                 min(members.size, SEEN_SAMPLE)).astype(np.int64)]
    lists = tree.query_ball_point(points[sample], (SEEN_WINDOW + SEEN_REACH) * spacing)
    w = np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists]))
    gi = ev_idx[w]
    lim = np.abs(hi_lim[gi] if above else lo_lim[gi])
    deep = gi[np.abs(values[gi]) <= 0.5 * lim]
    if deep.size < 2 * SEEN_K + 2:
        return 0.0
    deep = deep[facing(tree, ev_idx, values, normals, points, deep,
                       hi_lim if above else lo_lim, spacing)]
    if deep.size < 2 * SEEN_K + 2:
        return 0.0
    dtree = cKDTree(points[deep])
    # the reference: the surface around the component, between SEEN_INNER and SEEN_WINDOW
    # spacings from its points (the deep points at a defect's rim have lost the neighbours
    # inside it: their distances are larger; beyond the window a point's neighbours are cut off)
    r, _ = cKDTree(points[members]).query(points[deep], k=1,
                                          distance_upper_bound=SEEN_WINDOW * spacing)
    ring = deep[np.isfinite(r) & (r >= SEEN_INNER * spacing)]
    if ring.size < SEEN_K + 1:
        return 0.0
    ring = ring[np.linspace(0, ring.size - 1, min(ring.size, SEEN_RING)).astype(np.int64)]
    own = _kth_same_side(dtree, normals[deep], points[ring], normals[ring], SEEN_K, True)
    own = own[np.isfinite(own)]
    if own.size < SEEN_MIN_RING:
        return 0.0                  # no surface sampled around: nothing says it is seen under
    # no farther than that distance on a random sample SEEN_RING_SPARSEST times sparser than
    # the scan (a few deep points scattered around a large defect are no surface: 8 of them 3-5
    # spacings outside a dent 30 spacings across once made it a 'layer')
    ref = min(float(np.quantile(own, SEEN_QUANTILE)), _poisson_kth(SEEN_K, SEEN_QUANTILE)
              * SEEN_RING_SPARSEST * spacing)
    at = _kth_same_side(dtree, normals[deep], points[sample], normals[sample], SEEN_K, False)
    return float(np.mean(at <= ref))


#: Deep points looked at around a component's points, and the reach of the members around each,
#: in spacings (``seen_among``).
AMONG_REACH = 1.5
#: A deep point counts only where the surface its ``AMONG_K`` nearest deep neighbours form
#: (scan positions; looked for within ``AMONG_WINDOW`` spacings of its foot) is a surface, not a
#: row (its second spread at least ``AMONG_FLAT`` of its first), and faces the way its CAD
#: normal does, within ``AMONG_FACING`` (cosine: 45 degrees).
AMONG_K = 8
AMONG_WINDOW = 3.0
AMONG_FLAT = 0.1
AMONG_FACING = 0.7


def facing(tree, ev_idx, values, normals, points, idx, lim, spacing) -> np.ndarray:
    """Whether the surface through each deep point ``idx`` and its deep neighbours (a plane
    through their scan positions ``foot + d n``) faces along its CAD normal (``AMONG_*``);
    deep: ``|d|`` at most half ``|lim|`` (the per-point limit on the component's side).

    Under a layer it does: the part's own surface.  A dent on a convex edge pushes the points of
    one face nearer the other, which they then read against: their feet gather on a curve of
    that face, their scan positions lie in a sheet seen edge-on from it (the dented neighbour
    face), at every depth from 0 to the dent's; the deep ones among the dent's other points are
    that sheet (or, on a lattice, one row of it: no surface at all), not a surface under a layer
    (the wavy cube, a dent on its 90 degree edge: all its points were read as a reflection and
    the dented part showed no region).  At a coarser spacing that sheet is one row along a
    curve of this face, which the plane test passes (its curve spans a plane facing the
    normal): a deep point whose scan position may be the other face's, pushed beyond the limit
    (:func:`.region_folds.behind_other_face`), counts neither (the dent at 1/5 of its radius:
    3-6 such points made it a layer in 2 of 8 scans)."""
    idx = np.asarray(idx, np.int64)
    lists = tree.query_ball_point(points[idx], AMONG_WINDOW * spacing)
    near = ev_idx[np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists]))]
    near = near[np.abs(values[near]) <= 0.5 * np.abs(lim[near])]
    if near.size < 5:
        return np.zeros(idx.size, bool)
    S = points[near] + values[near, None] * normals[near]
    k = min(AMONG_K, near.size)
    _, j = cKDTree(S).query(points[idx] + values[idx, None] * normals[idx], k=k)
    Q = S[j.reshape(idx.size, k)]
    Q = Q - Q.mean(axis=1, keepdims=True)
    lam, V = np.linalg.eigh(np.einsum("ika,ikb->iab", Q, Q))
    ok = (lam[:, 1] >= AMONG_FLAT * lam[:, 2]) & \
        (np.abs(np.einsum("ia,ia->i", V[:, :, 0], normals[idx])) >= AMONG_FACING)
    if ok.any():
        # nor a point of the other face pushed in beyond the limit (a row of them, one
        # spacing apart along a curve of this face, passes the plane test above)
        ok[ok] = ~may_be_folded(tree, ev_idx, values, normals, points, idx[ok], (lim,),
                                spacing)[0]
    return ok


def seen_among(tree, ev_idx, values, normals, points, members, above, lo_lim, hi_lim,
               spacing) -> int:
    """How many deep-in-tolerance points (``|d|`` at most half the limit, on the component's side
    of the part: normal within 60 degrees) lie *among* the out-of-tolerance points ``members``
    of one component (scan indices, all on one side: ``above``): inside the convex hull, in the
    point's own tangent plane, of the members within ``AMONG_REACH`` spacings of it (no angular
    gap of half a turn or more between them).

    A real defect replaces the surface: every point of its own surface inside it is out of
    tolerance (or in the band where ``|d|`` climbs to the limit), and a deep point lies outside
    the defect; for a convex defect (a dent, a bump, a pit, a straight scratch) the members
    within reach of an outside point all lie on one side of it, so the count is 0 whatever the
    sampling or the defect's size.  A layer (a reflection, a ghost) lies over the surface: the
    surface's own points are seen among its points, however sparsely the surface is sampled
    under it (:func:`seen_around` measures that density against the surface around, and a
    reflection's component sits where the surface under it happens to be sparse).  A deep point
    counts only on a surface facing the way the part does there (:func:`facing`), here as in
    :func:`seen_around`."""
    members = np.asarray(members)
    members = members[values[members] > hi_lim[members]] if above else \
        members[values[members] < lo_lim[members]]
    if members.size < 3:
        return 0
    reach = AMONG_REACH * spacing
    lists = tree.query_ball_point(points[members], reach)
    w = np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists]))
    gi = ev_idx[w]
    lim = np.abs(hi_lim[gi] if above else lo_lim[gi])
    deep = gi[np.abs(values[gi]) <= 0.5 * lim]
    if deep.size == 0:
        return 0
    k = min(members.size, 32)
    d, j = cKDTree(points[members]).query(points[deep], k=k, distance_upper_bound=reach)
    d, j = d.reshape(deep.size, k), j.reshape(deep.size, k)
    jj = members[np.minimum(j, members.size - 1)]
    qn = normals[deep]
    ok = np.isfinite(d) & (np.einsum("ijk,ik->ij", normals[jj], qn) > SEEN_SAME_SIDE)
    e1, e2 = _basis(qn)
    D = points[jj] - points[deep][:, None, :]
    ang = np.where(ok, np.arctan2(np.einsum("ijk,ik->ij", D, e2), np.einsum("ijk,ik->ij", D, e1)),
                   np.inf)
    ang.sort(axis=1)
    n_ok = ok.sum(axis=1)
    sel = n_ok >= 3
    if not sel.any():
        return 0
    ang, n_ok = ang[sel], n_ok[sel]
    # the widest gap between consecutive directions, the wrap-around included
    k_all = np.arange(ang.shape[1] - 1)[None]
    gaps = np.where(k_all + 1 < n_ok[:, None],
                    np.diff(np.where(np.isfinite(ang), ang, 0.0), axis=1), -np.inf)
    last = np.take_along_axis(ang, (n_ok - 1)[:, None], axis=1)[:, 0]
    widest = np.maximum(gaps.max(axis=1), ang[:, 0] + 2.0 * np.pi - last)
    among = deep[sel][widest < np.pi]
    if among.size == 0:
        return 0
    return int(np.count_nonzero(facing(tree, ev_idx, values, normals, points, among,
                                        hi_lim if above else lo_lim, spacing)))
