"""Model points: a close-to-uniform 3D sampling of a model's surface (thesis §7.3, Paper I).

:func:`sample_model` turns a :class:`~shapeverify.cad.model.Model` into
:class:`~shapeverify.cad.model.ModelPoints`: points with outward normals, orthonormal tangent
frames, the (face, u, v) they come from, the half extent of the small tangent patch each point
stands for, and whether the point is near a free edge of the part.

How the points are made
-----------------------
*CAD models.*  Uniform in parameter space is far from uniform in 3D (clustered knots, rational
weights, degenerate poles), so each face is sampled through its metric:

1. The face's parameter box (the bounding box of its outer trimming loop, clipped to the
   surface domain) is split into tiles until, inside each tile, the product grid described next
   oversamples the surface by at most about 3x (a pole gets its own small tiles).
2. In a tile, ``|S_u|`` and ``|S_v|`` are measured on a coarse grid; the parameter lines are
   placed at equal steps of the largest arc length (``max_v int |S_u| du`` and
   ``max_u int |S_v| dv``) so that neighbouring candidates are at most about ``spacing / 2``
   apart in 3D (cell centres: nothing is placed exactly on a tile edge or a pole).
3. Candidates outside the trims (``Face.contains``) are dropped; the rest are evaluated exactly
   with :class:`~shapeverify.cad.nurbs.NurbsSurface` (points, S_u, S_v).
4. A Poisson-disk thinning (greedy, in grid order, spatial hash with cells of the disk
   radius ``0.85 * spacing``) keeps a candidate only if no kept point of the same side of the
   material lies within the radius (points whose normals differ by more than 120 degrees, e.g.
   the two skins of a thin blade, do not suppress each other).  It runs per face and then once
   over all faces, so face seams are not doubled.  Visiting the candidates in grid (scan-line)
   order packs the points almost hexagonally: measured on a sphere, the nearest-neighbour
   distance is 0.85-1.15 x spacing (median 0.96), every surface point lies within 0.9 x spacing
   of a model point, and the count is about ``area / spacing**2``.  On flat, regular parameter
   grids the packing can get close to hexagonal at the disk radius (nearest neighbour 0.85-0.9 x
   spacing, up to about 1.5 x ``area / spacing**2`` points; seen on strongly sheared patches).

*Mesh models.*  Candidates on every triangle on a randomly shifted square lattice of step
``spacing / 2`` in the triangle's plane (aligned with its longest edge), then the same thinning
(in triangle order); ``face`` is the triangle index and ``uv = (u, v)`` the barycentric
coordinates with ``p = A + u (B - A) + v (C - A)`` for the triangle's vertices ``A, B, C``.
Normals follow the triangle winding (right-hand rule), i.e. they are outward if the mesh is
consistently oriented.

*Point-cloud models.*  The cloud is thinned (random order, without normals, disk radius
``0.425 * spacing``); normals come from ``model.cloud_normals`` when given, otherwise from a PCA
of the 12 nearest thinned points, oriented away from the cloud's centroid (a heuristic that is
right for closed, roughly star-shaped objects and for single scanner views of convex parts; it
can flip normals in concavities).  Then the thinning at ``0.85 * spacing`` with normals (random
order).  The model points are cloud points; ``face = -1``, ``uv = 0``, ``boundary = False`` (a
cloud has no known edges).

``half_extent`` is measured from the six nearest model points: along ``tangent_u`` (``v``) it is
0.6 x the largest projection of their offsets on ``tangent_u`` (``v``), clipped to
``[0.5, 1.5] * spacing``, so the tangent patches cover the surface with a small overlap.
``tangent_u`` is the direction of ``S_u`` (CAD), of the edge ``B - A`` (mesh) or arbitrary (cloud).
``boundary`` marks points within ``spacing`` (3D distance) of a free edge: for CAD faces the
loop segments flagged in ``Face.loop_free``, for meshes the edges used by a single triangle.

The CAD sampling is deterministic.  Randomness (mesh lattice offsets, the visiting order for
point clouds) comes only from ``rng``; ``rng=None`` uses a fixed seed (0), so the same model and
spacing always give the same points.

References
----------
Bergström (2011), thesis §7.3 (trimmed faces) and Paper I (model points and tangent patches).
Bridson, "Fast Poisson disk sampling in arbitrary dimensions", SIGGRAPH sketches 2007 (the
spatial-hash idea for the disk test).
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

__all__ = ["sample_model", "needed_spacing", "MAX_POINTS"]

logger = logging.getLogger(__name__)

#: Largest number of model points :func:`sample_model` agrees to make.
MAX_POINTS = 20_000_000

_RADIUS = 0.85  # Poisson-disk radius / spacing
_CAND = 0.5  # candidate step / spacing
_COS_SAME_SIDE = -0.5  # points whose normals differ by more than 120 deg do not suppress each other
_MAX_TILE_CANDIDATES = 2_000_000
_BATCH_CANDIDATES = 4_000_000
_MAX_DEPTH = 14


# ----------------------------------------------------------------------------------- public
def sample_model(model, spacing, rng=None):
    """Sample a model's surface with points about ``spacing`` apart in 3D.

    Parameters
    ----------
    model : shapeverify.cad.model.Model
        ``kind`` "cad" (trimmed NURBS faces), "mesh" or "points".
    spacing : float > 0
        Target distance between neighbouring model points, in model units (mm).
    rng : None, int or numpy.random.Generator
        Mesh lattice offsets and point-cloud visiting order; None means a fixed seed
        (repeatable result).  CAD sampling does not use it.

    Returns
    -------
    ModelPoints
        ``points (N, 3)``, ``normals (N, 3)`` outward unit, ``face (N,)`` int32, ``uv (N, 2)``,
        ``tangent_u``/``tangent_v (N, 3)`` (orthonormal with the normal), ``half_extent (N, 2)``,
        ``boundary (N,)`` bool, ``spacing``.

    Raises
    ------
    ValueError
        ``spacing`` not a finite number > 0, or so small that more than :data:`MAX_POINTS`
        points would be made (the message gives the smallest acceptable spacing); a model
        without any surface to sample.

    Examples
    --------
    >>> from shapeverify.cad.nurbs import sphere
    >>> from shapeverify.cad.model import Face, Model
    >>> f = Face(sphere(10.0), loops=(np.array([[0, 0], [1, 0], [1, 1], [0, 1.]]),),
    ...          loop_free=(np.zeros(4, bool),), reversed=False)
    >>> m = Model(faces=(f,), unit="mm", scale_to_mm=1.0, source="sphere", kind="cad",
    ...           vertices=None, triangles=None, cloud_normals=None)
    >>> mp = sample_model(m, 1.0)
    >>> 1000 < len(mp.points) < 1600     # area 4 pi 10^2 = 1257 mm^2
    True
    """
    try:
        s = float(spacing)
    except (TypeError, ValueError):
        raise ValueError(f"spacing must be a number > 0 (mm), got {spacing!r}") from None
    if not (math.isfinite(s) and s > 0):
        raise ValueError(f"spacing must be finite and > 0 (mm), got {spacing!r}")
    rng = np.random.default_rng(0 if rng is None else rng)
    kind = getattr(model, "kind", "cad")
    if kind == "cad":
        parts = _sample_cad(model, s, rng)
    elif kind == "mesh":
        parts = _sample_mesh(model, s, rng)
    elif kind == "points":
        parts = _sample_cloud(model, s, rng)
    else:
        raise ValueError(f"model.kind must be 'cad', 'mesh' or 'points', got {kind!r}")
    return _finish(parts, s, model)


def needed_spacing(model) -> float:
    """The coarsest spacing (mm) that still represents a mesh or point-cloud model fully.

    The default spacing of :func:`shapeverify.prepare` is ``size / 500`` -- right for curved
    CAD faces, whose tangent patches need it, but wasteful for a mesh of a few large flat
    triangles (a 60-triangle part got about 250,000 model points, and its preparation cost
    followed them, not the geometry) or for a cloud sparser than that.

    * mesh: about 4 model points per triangle (at least 10,000 in all): a flat triangle is
      represented exactly by its tangent patches, and the exact mode projects onto the
      triangles themselves; ``sqrt(area / max(10_000, 4 T))``.
    * point cloud: the cloud's own median nearest-neighbour distance (model points are cloud
      points; a finer spacing only adds tree cells between them).
    * CAD: 0 (no lower bound; curved faces need the default).

    ``prepare`` uses ``max(size / 500, needed_spacing(model))`` when no spacing is given.

    Examples
    --------
    >>> from shapeverify.cad.model import Model
    >>> V = np.array([[0, 0, 0], [100, 0, 0], [0, 100, 0.]])
    >>> m = Model(kind="mesh", vertices=V, triangles=np.array([[0, 1, 2]]), source="tri")
    >>> round(needed_spacing(m), 4)      # sqrt(5000 mm^2 / 10000)
    0.7071
    """
    kind = getattr(model, "kind", "cad")
    if kind == "mesh":
        V = np.asarray(model.vertices, dtype=np.float64)
        T = np.asarray(model.triangles, dtype=np.int64)
        if len(T) == 0:
            return 0.0
        area = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]),
                                    axis=1).sum()
        return float(np.sqrt(area / max(_MESH_MIN_POINTS, _MESH_POINTS_PER_TRIANGLE * len(T))))
    if kind == "points":
        X = np.asarray(model.vertices, dtype=np.float64)
        if X.ndim != 2 or len(X) < 2:
            return 0.0
        # a repeatable subsample is enough for a median
        sub = X[np.random.default_rng(0).permutation(len(X))[:20_000]]
        d, _ = cKDTree(X).query(sub, k=2)
        return float(np.median(d[:, 1]))
    return 0.0


_MESH_MIN_POINTS = 10_000
_MESH_POINTS_PER_TRIANGLE = 4


# ------------------------------------------------------------------------------ thinning
@njit(cache=True)
def _hash_slot(keys, key, mask):
    h = (key * 0x9E3779B1 + (key >> 29)) & mask
    while keys[h] != -1 and keys[h] != key:
        h = (h + 1) & mask
    return h


@njit(cache=True)
def _thin_kernel(P, N, r, cos_min, use_normals, keep):
    """Greedy Poisson-disk thinning in the given order (spatial hash, cells of size r)."""
    n = P.shape[0]
    if n == 0:
        return
    lo = np.empty(3)
    for k in range(3):
        lo[k] = P[0, k]
        for i in range(n):
            if P[i, k] < lo[k]:
                lo[k] = P[i, k]
    inv = 1.0 / r
    cell = np.empty((n, 3), np.int64)
    dims = np.zeros(3, np.int64)
    for i in range(n):
        for k in range(3):
            c = np.int64((P[i, k] - lo[k]) * inv)
            cell[i, k] = c
            if c + 1 > dims[k]:
                dims[k] = c + 1
    size = 1
    while size < 2 * n + 16:
        size *= 2
    mask = size - 1
    keys = np.full(size, -1, np.int64)
    head = np.full(size, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    r2 = r * r
    for i in range(n):
        ok = True
        for dx in range(-1, 2):
            cx = cell[i, 0] + dx
            if cx < 0 or cx >= dims[0] or not ok:
                continue
            for dy in range(-1, 2):
                cy = cell[i, 1] + dy
                if cy < 0 or cy >= dims[1] or not ok:
                    continue
                for dz in range(-1, 2):
                    cz = cell[i, 2] + dz
                    if cz < 0 or cz >= dims[2]:
                        continue
                    key = cx + dims[0] * (cy + dims[1] * cz)
                    h = _hash_slot(keys, key, mask)
                    j = head[h] if keys[h] == key else -1
                    while j >= 0:
                        d0 = P[i, 0] - P[j, 0]
                        d1 = P[i, 1] - P[j, 1]
                        d2 = P[i, 2] - P[j, 2]
                        if d0 * d0 + d1 * d1 + d2 * d2 < r2:
                            if not use_normals or (N[i, 0] * N[j, 0] + N[i, 1] * N[j, 1]
                                                   + N[i, 2] * N[j, 2]) > cos_min:
                                ok = False
                                break
                        j = nxt[j]
                    if not ok:
                        break
        if ok:
            keep[i] = True
            key = cell[i, 0] + dims[0] * (cell[i, 1] + dims[1] * cell[i, 2])
            h = _hash_slot(keys, key, mask)
            keys[h] = key
            nxt[i] = head[h]
            head[h] = i


def _thin(P, N, r, order=None, use_normals=True):
    """Indices (into P) of the points kept by the Poisson-disk thinning, visiting ``order``
    (default: the given order)."""
    if order is None:
        Po, No = np.ascontiguousarray(P), (np.ascontiguousarray(N) if use_normals else None)
    else:
        Po = np.ascontiguousarray(P[order])
        No = np.ascontiguousarray(N[order]) if use_normals else None
    if len(Po) == 0:
        return np.empty(0, np.int64)
    if No is None:
        No = np.zeros((1, 3))
    ext = Po.max(axis=0) - Po.min(axis=0)
    if np.prod(ext / r + 2.0) > 2.0 ** 62:
        raise ValueError(f"spacing {r / _RADIUS!r} is too small for a model of extent "
                         f"{ext.max():.6g}; use a larger spacing")
    keep = np.zeros(len(Po), np.bool_)
    _thin_kernel(Po, No, float(r), _COS_SAME_SIDE, use_normals, keep)
    kept = np.flatnonzero(keep)
    return kept if order is None else np.asarray(order)[kept]


# ------------------------------------------------------------------------------------- CAD
class _Parts:
    """Accumulated sample columns (points, normals, Su-direction, face, uv)."""

    def __init__(self):
        self.P, self.N, self.T, self.F, self.UV = [], [], [], [], []

    def add(self, P, N, T, F, UV):
        self.P.append(P)
        self.N.append(N)
        self.T.append(T)
        self.F.append(F)
        self.UV.append(UV)

    def cat(self):
        if not self.P:
            return (np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                    np.empty(0, np.int32), np.empty((0, 2)))
        return (np.concatenate(self.P), np.concatenate(self.N), np.concatenate(self.T),
                np.concatenate(self.F).astype(np.int32), np.concatenate(self.UV))


def _cross(a, b):
    """Row-wise cross product (faster than np.cross for (N, 3))."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _face_box(face):
    (u0, u1), (v0, v1) = face.surface.domain
    if len(face.loops) and len(face.loops[0]):
        lo = face.loops[0].min(axis=0)
        hi = face.loops[0].max(axis=0)
        ua, va = max(u0, lo[0]), max(v0, lo[1])
        ub, vb = min(u1, hi[0]), min(v1, hi[1])
        if ub > ua and vb > va:
            return (ua, ub), (va, vb)
    return (u0, u1), (v0, v1)


def _n_coarse(knots, a, b):
    inner = np.count_nonzero((knots > a) & (knots < b))
    return int(np.clip(3 * (inner + 1) + 2, 5, 33))


def _metric(surface, box):
    """Coarse-grid arc-length data of a tile: (U, gu, V, gv, area)."""
    (ua, ub), (va, vb) = box
    U = np.linspace(ua, ub, _n_coarse(surface.knots_u, ua, ub))
    V = np.linspace(va, vb, _n_coarse(surface.knots_v, va, vb))
    uu, vv = np.meshgrid(U, V, indexing="ij")
    d = surface.derivatives(uu.ravel(), vv.ravel(), 1)
    su = np.linalg.norm(d[:, 1, 0], axis=1).reshape(uu.shape)
    sv = np.linalg.norm(d[:, 0, 1], axis=1).reshape(uu.shape)
    da = np.linalg.norm(np.cross(d[:, 1, 0], d[:, 0, 1]), axis=1).reshape(uu.shape)
    area = np.trapezoid(np.trapezoid(da, V, axis=1), U)
    return U, su, V, sv, area


def _plan(surface, box, h, depth=0, metric=None):
    """Split a parameter box into tiles; return [(box, U, gu, V, gv)] and the area estimate."""
    U, su, V, sv, area = _metric(surface, box) if metric is None else metric
    gu, gv = su.max(axis=1), sv.max(axis=0)  # largest |Su| over v at each u, |Sv| over u at each v
    Lu = np.trapezoid(gu, U)
    Lv = np.trapezoid(gv, V)
    n_grid = (Lu / h + 1) * (Lv / h + 1)
    n_ideal = area / (h * h)
    # how much the u-arc length varies across v lines (and vice versa): splitting only helps
    # against that, not against a sheared parametrisation (|Su x Sv| << |Su| |Sv|)
    lu_v = np.trapezoid(su, U, axis=0)  # u-arc length of each v line
    lv_u = np.trapezoid(sv, V, axis=1)
    var_u = Lu / max(lu_v.mean(), 1e-300)
    var_v = Lv / max(lv_u.mean(), 1e-300)
    split = depth < _MAX_DEPTH and max(Lu, Lv) > 4 * h and (
        (n_grid > 3.0 * n_ideal + 64 and max(var_u, var_v) > 1.25)
        or n_grid > _MAX_TILE_CANDIDATES)
    if not split:
        return [(box, U, gu, V, gv)], area
    # split across the direction whose arc length varies most along the other one
    (ua, ub), (va, vb) = box
    if n_grid > _MAX_TILE_CANDIDATES and max(var_u, var_v) < 1.5:
        split_v = Lv > Lu
    else:
        split_v = var_u >= var_v
    if split_v:
        vm = 0.5 * (va + vb)
        halves = [((ua, ub), (va, vm)), ((ua, ub), (vm, vb))]
    else:
        um = 0.5 * (ua + ub)
        halves = [((ua, um), (va, vb)), ((um, ub), (va, vb))]
    tiles, area = [], 0.0
    for b in halves:
        t, a = _plan(surface, b, h, depth + 1)
        tiles += t
        area += a
    return tiles, area


def _arc_params(X, g, h):
    """Parameters at cell centres of equal arc-length steps <= h along density g(X)."""
    G = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(X))])
    n = max(1, int(math.ceil(G[-1] / h)))
    if G[-1] <= 0:
        return np.linspace(X[0], X[-1], 2 * n + 1)[1::2]
    t = (np.arange(n) + 0.5) * (G[-1] / n)
    # G may be flat where g == 0: interpolate on the strictly increasing part
    keep = np.concatenate([[True], np.diff(G) > 0])
    return np.interp(t, G[keep], X[keep])


def _tile_grid(tile, h):
    _, U, gu, V, gv = tile
    u = _arc_params(U, gu, h)
    v = _arc_params(V, gv, h)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    return np.column_stack([uu.ravel(), vv.ravel()])


def _sample_cad(model, s, rng):
    faces = tuple(model.faces)
    if not faces:
        raise ValueError(f"model {getattr(model, 'source', '')!r} has no faces to sample")
    h = _CAND * s
    r = _RADIUS * s
    boxes = [_face_box(face) for face in faces]
    metrics = [_metric(face.surface, box) for face, box in zip(faces, boxes)]
    _check_count(sum(mt[-1] for mt in metrics), s)  # before any fine work
    plans = [_plan(face.surface, box, h, metric=mt)[0]
             for face, box, mt in zip(faces, boxes, metrics)]
    parts = _Parts()
    for fi, (face, tiles) in enumerate(zip(faces, plans)):
        batch, n_batch = [], 0
        for k, tile in enumerate(tiles):
            uv = _tile_grid(tile, h)
            batch.append(uv)
            n_batch += len(uv)
            if n_batch >= _BATCH_CANDIDATES or k == len(tiles) - 1:
                _cad_batch(face, fi, np.concatenate(batch), r, parts)
                batch, n_batch = [], 0
    P, N, T, F, UV = parts.cat()
    idx = _thin(P, N, r)  # across faces, in face order
    boundary = _cad_free_edge_flags(faces, P[idx], s)
    return P[idx], N[idx], T[idx], F[idx], UV[idx], boundary


def _cad_batch(face, fi, uv, r, parts):
    if len(face.loops):
        uv = uv[np.asarray(face.contains(uv), dtype=bool)]
    if len(uv) == 0:
        return
    d = face.surface.derivatives(uv[:, 0], uv[:, 1], 1)
    P, su, sv = d[:, 0, 0], d[:, 1, 0], d[:, 0, 1]
    n = _cross(su, sv)
    ln = np.sqrt(np.einsum("ij,ij->i", n, n))
    nsu = np.sqrt(np.einsum("ij,ij->i", su, su))
    nsv = np.sqrt(np.einsum("ij,ij->i", sv, sv))
    good = (ln > 1e-12 * nsu * nsv) & (nsu > 1e-10 * nsv) & (nsv > 1e-10 * nsu)
    n /= np.where(good, ln, 1.0)[:, None]
    if face.reversed:
        n = -n
    if good.all():
        idx = _thin(P, n, r)  # grid (scan-line) order: denser, more regular packing than random
    else:
        logger.debug("face %d: %d candidates at degenerate surface points skipped",
                     fi, int((~good).sum()))
        idx = _thin(P, n, r, np.flatnonzero(good))
    t = su[idx] / nsu[idx, None]
    parts.add(P[idx], n[idx], t, np.full(len(idx), fi, np.int32), uv[idx])


def _cad_free_edge_flags(faces, pts, s):
    samples = []
    for face in faces:
        (u0, u1), (v0, v1) = face.surface.domain
        for loop, free in zip(face.loops, face.loop_free):
            free = np.asarray(free, dtype=bool)
            if len(loop) < 2 or not free.any():
                continue
            a = loop[free]
            b = np.roll(loop, -1, axis=0)[free]
            lo, hi = (u0, v0), (u1, v1)
            a, b = np.clip(a, lo, hi), np.clip(b, lo, hi)
            A = face.surface.evaluate(a[:, 0], a[:, 1])
            B = face.surface.evaluate(b[:, 0], b[:, 1])
            k = np.maximum(1, np.ceil(np.linalg.norm(B - A, axis=1) / (0.25 * s))).astype(int)
            seg = np.repeat(np.arange(len(a)), k)
            tt = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
            uv = a[seg] + tt[:, None] * (b[seg] - a[seg])
            samples.append(face.surface.evaluate(uv[:, 0], uv[:, 1]))
    return _near(samples, pts, s)


def _near(samples, pts, s):
    if not samples or len(pts) == 0:
        return np.zeros(len(pts), bool)
    tree = cKDTree(np.concatenate(samples))
    dist, _ = tree.query(pts, k=1, distance_upper_bound=s)
    return np.isfinite(dist)


def _check_count(area, s):
    n = area / (s * s)
    if not np.isfinite(n) or n > MAX_POINTS:
        smin = math.sqrt(area / MAX_POINTS) if np.isfinite(area) else float("nan")
        raise ValueError(
            f"spacing {s!r} mm on a surface of about {area:.6g} mm^2 would make about {n:.3g} "
            f"model points (limit {MAX_POINTS:,}); use spacing >= {smin:.3g} mm")


# ------------------------------------------------------------------------------------ mesh
@njit(cache=True)
def _lattice_count_fill(A, B, C, h, off, fill, tri, bary):
    """Points of a shifted square lattice (step h) inside each triangle (count; then fill)."""
    m = 0
    for t in range(A.shape[0]):
        e = np.empty((3, 3))
        for k in range(3):
            e[0, k] = B[t, k] - A[t, k]
            e[1, k] = C[t, k] - A[t, k]
            e[2, k] = C[t, k] - B[t, k]
        # longest edge direction as the lattice's first axis
        best, lb = 0, -1.0
        for q in range(3):
            lq = e[q, 0] ** 2 + e[q, 1] ** 2 + e[q, 2] ** 2
            if lq > lb:
                best, lb = q, lq
        if lb <= 0.0:
            continue
        ax = e[best] / math.sqrt(lb)
        nrm = np.empty(3)
        nrm[0] = e[0, 1] * e[1, 2] - e[0, 2] * e[1, 1]
        nrm[1] = e[0, 2] * e[1, 0] - e[0, 0] * e[1, 2]
        nrm[2] = e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0]
        ln = math.sqrt(nrm[0] ** 2 + nrm[1] ** 2 + nrm[2] ** 2)
        if ln <= 0.0:
            continue
        nrm /= ln
        ay = np.empty(3)
        ay[0] = nrm[1] * ax[2] - nrm[2] * ax[1]
        ay[1] = nrm[2] * ax[0] - nrm[0] * ax[2]
        ay[2] = nrm[0] * ax[1] - nrm[1] * ax[0]
        # 2-D coordinates of B and C relative to A
        bx = e[0, 0] * ax[0] + e[0, 1] * ax[1] + e[0, 2] * ax[2]
        by = e[0, 0] * ay[0] + e[0, 1] * ay[1] + e[0, 2] * ay[2]
        cx = e[1, 0] * ax[0] + e[1, 1] * ax[1] + e[1, 2] * ax[2]
        cy = e[1, 0] * ay[0] + e[1, 1] * ay[1] + e[1, 2] * ay[2]
        det = bx * cy - by * cx
        if det == 0.0:
            continue
        x0, x1 = min(0.0, bx, cx), max(0.0, bx, cx)
        y0, y1 = min(0.0, by, cy), max(0.0, by, cy)
        i0 = math.ceil(x0 / h - off[t, 0])
        j0 = math.ceil(y0 / h - off[t, 1])
        i1 = math.floor(x1 / h - off[t, 0])
        j1 = math.floor(y1 / h - off[t, 1])
        for i in range(i0, i1 + 1):
            x = (i + off[t, 0]) * h
            for j in range(j0, j1 + 1):
                y = (j + off[t, 1]) * h
                u = (x * cy - y * cx) / det
                v = (bx * y - by * x) / det
                if u >= 0.0 and v >= 0.0 and u + v <= 1.0:
                    if fill:
                        tri[m] = t
                        bary[m, 0] = u
                        bary[m, 1] = v
                    m += 1
    return m


def _sample_mesh(model, s, rng):
    V = np.asarray(model.vertices, dtype=np.float64)
    Tr = np.asarray(model.triangles, dtype=np.int64)
    if len(Tr) == 0:
        raise ValueError(f"mesh model {getattr(model, 'source', '')!r} has no triangles")
    A, B, C = V[Tr[:, 0]], V[Tr[:, 1]], V[Tr[:, 2]]
    cr = np.cross(B - A, C - A)
    dbl = np.linalg.norm(cr, axis=1)
    _check_count(0.5 * dbl.sum(), s)
    with np.errstate(invalid="ignore", divide="ignore"):
        tn = cr / dbl[:, None]
    h = _CAND * s
    r = _RADIUS * s
    parts = _Parts()
    # batches of triangles with about _BATCH_CANDIDATES candidates each
    est = np.cumsum(0.5 * dbl / (h * h) + 1.0)
    cuts = np.searchsorted(est, np.arange(_BATCH_CANDIDATES, est[-1], _BATCH_CANDIDATES))
    edges = np.unique(np.concatenate([[0], cuts, [len(Tr)]]))
    for start, stop in zip(edges[:-1], edges[1:]):
        sl = slice(start, stop)
        off = rng.random((stop - start, 2))
        a, b, c = (np.ascontiguousarray(X[sl]) for X in (A, B, C))
        m = _lattice_count_fill(a, b, c, h, off, False, np.empty(0, np.int64), np.empty((0, 2)))
        tri = np.empty(m, np.int64)
        bary = np.empty((m, 2))
        _lattice_count_fill(a, b, c, h, off, True, tri, bary)
        tri += start
        P = A[tri] + bary[:, :1] * (B[tri] - A[tri]) + bary[:, 1:] * (C[tri] - A[tri])
        N = tn[tri]
        idx = _thin(P, N, r)  # lattice order, triangle by triangle (coherent, regular)
        t = B[tri[idx]] - A[tri[idx]]
        t /= np.linalg.norm(t, axis=1)[:, None]
        parts.add(P[idx], N[idx], t, tri[idx].astype(np.int32), bary[idx])
    P, N, T, F, UV = parts.cat()
    idx = _thin(P, N, r)
    boundary = _mesh_free_edge_flags(V, Tr, P[idx], s)
    return P[idx], N[idx], T[idx], F[idx], UV[idx], boundary


def _mesh_free_edges(Tr):
    """Edges (E, 2) used by exactly one triangle."""
    e = np.concatenate([Tr[:, [0, 1]], Tr[:, [1, 2]], Tr[:, [2, 0]]])
    e = np.sort(e, axis=1)
    uniq, cnt = np.unique(e, axis=0, return_counts=True)
    return uniq[cnt == 1]


def _mesh_free_edge_flags(V, Tr, pts, s):
    free = _mesh_free_edges(Tr)
    if len(free) == 0:
        return np.zeros(len(pts), bool)
    A, B = V[free[:, 0]], V[free[:, 1]]
    k = np.maximum(1, np.ceil(np.linalg.norm(B - A, axis=1) / (0.25 * s))).astype(np.int64)
    seg = np.repeat(np.arange(len(A)), k)
    tt = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
    samples = np.concatenate([A[seg] + tt[:, None] * (B[seg] - A[seg]), B])
    return _near([samples], pts, s)


# ----------------------------------------------------------------------------- point cloud
def _sample_cloud(model, s, rng):
    X = np.asarray(model.vertices, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) == 0:
        raise ValueError(f"point-cloud model has no points (vertices shape {X.shape})")
    given = getattr(model, "cloud_normals", None)
    r = _RADIUS * s
    # 1. thin without normals to half the final radius (cheap normals on fewer points)
    pre = _thin(X, X, 0.5 * r, rng.permutation(len(X)), use_normals=False)
    pre.sort()
    Xp = X[pre]
    if given is not None:
        N = np.asarray(given, dtype=np.float64)[pre]
        N = N / np.linalg.norm(N, axis=1)[:, None]
    else:
        N = _pca_normals(Xp)
    # 2. final thinning with the same-side test
    idx = _thin(Xp, N, r, rng.permutation(len(Xp)))
    idx.sort()
    P, N = Xp[idx], N[idx]
    T = _any_tangent(N)
    n = len(P)
    return P, N, T, np.full(n, -1, np.int32), np.zeros((n, 2)), np.zeros(n, bool)


@njit(cache=True)
def _neighbour_cov(X, nb, out):
    """Covariance (3, 3) of each point's neighbours (rows of nb)."""
    k = nb.shape[1]
    for i in range(X.shape[0]):
        m0 = m1 = m2 = 0.0
        for j in range(k):
            q = nb[i, j]
            m0 += X[q, 0]
            m1 += X[q, 1]
            m2 += X[q, 2]
        m0 /= k
        m1 /= k
        m2 /= k
        c00 = c01 = c02 = c11 = c12 = c22 = 0.0
        for j in range(k):
            q = nb[i, j]
            a = X[q, 0] - m0
            b = X[q, 1] - m1
            c = X[q, 2] - m2
            c00 += a * a
            c01 += a * b
            c02 += a * c
            c11 += b * b
            c12 += b * c
            c22 += c * c
        out[i, 0, 0] = c00
        out[i, 0, 1] = out[i, 1, 0] = c01
        out[i, 0, 2] = out[i, 2, 0] = c02
        out[i, 1, 1] = c11
        out[i, 1, 2] = out[i, 2, 1] = c12
        out[i, 2, 2] = c22


def _pca_normals(X, k=12):
    """Unit normals by PCA of the k nearest points, oriented away from the centroid."""
    k = min(k, len(X))
    if k < 3:
        raise ValueError(f"need at least 3 points to estimate normals, got {len(X)}")
    _, nb = cKDTree(X).query(X, k=k, workers=2)
    cov = np.empty((len(X), 3, 3))
    _neighbour_cov(X, np.ascontiguousarray(nb, dtype=np.int64), cov)
    _, vec = np.linalg.eigh(cov)
    N = np.ascontiguousarray(vec[:, :, 0])
    flip = np.einsum("ij,ij->i", N, X - X.mean(axis=0)) < 0
    N[flip] *= -1
    return N


def _any_tangent(N):
    """A unit vector perpendicular to each normal."""
    a = np.zeros_like(N)
    ax = np.argmin(np.abs(N), axis=1)
    a[np.arange(len(N)), ax] = 1.0
    t = np.cross(N, a)
    return t / np.linalg.norm(t, axis=1)[:, None]


# ---------------------------------------------------------------------------------- finish
def _finish(parts, s, model):
    from shapeverify.cad.model import ModelPoints

    P, N, T, F, UV, boundary = parts
    if len(P) == 0:
        raise ValueError(f"sampling {getattr(model, 'source', 'the model')!r} at spacing {s} "
                         "produced no points (all faces trimmed away or degenerate)")
    # orthonormal frame: t_u = Su direction projected into the tangent plane, t_v = n x t_u
    T = T - np.einsum("ij,ij->i", T, N)[:, None] * N
    T /= np.linalg.norm(T, axis=1)[:, None]
    Tv = _cross(N, T)
    half = _half_extents(P, T, Tv, s)
    return ModelPoints(points=P, normals=N, face=F.astype(np.int32), uv=UV, tangent_u=T,
                       tangent_v=Tv, half_extent=half, boundary=boundary, spacing=s)


@njit(cache=True)
def _max_projections(P, nb, Tu, Tv, out):
    """out[i] = max over neighbours j of |(P_j - P_i) . Tu_i|, |(P_j - P_i) . Tv_i|."""
    for i in range(P.shape[0]):
        mu = 0.0
        mv = 0.0
        for c in range(1, nb.shape[1]):
            j = nb[i, c]
            d0 = P[j, 0] - P[i, 0]
            d1 = P[j, 1] - P[i, 1]
            d2 = P[j, 2] - P[i, 2]
            pu = abs(d0 * Tu[i, 0] + d1 * Tu[i, 1] + d2 * Tu[i, 2])
            pv = abs(d0 * Tv[i, 0] + d1 * Tv[i, 1] + d2 * Tv[i, 2])
            if pu > mu:
                mu = pu
            if pv > mv:
                mv = pv
        out[i, 0] = mu
        out[i, 1] = mv


def _half_extents(P, Tu, Tv, s, k=6):
    n = len(P)
    half = np.full((n, 2), s)
    if n > 1:
        kk = min(k, n - 1)
        _, nb = cKDTree(P).query(P, k=kk + 1, workers=2)
        proj = np.empty((n, 2))
        _max_projections(np.ascontiguousarray(P), np.ascontiguousarray(nb, dtype=np.int64),
                         np.ascontiguousarray(Tu), np.ascontiguousarray(Tv), proj)
        half = 0.6 * proj
    return np.clip(half, 0.5 * s, 1.5 * s)
