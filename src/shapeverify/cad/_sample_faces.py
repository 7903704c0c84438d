"""Model points on trimmed NURBS faces: tiles, arc-length grids, trims, thinning (private).

See :mod:`shapeverify.cad.sampling` for the method (steps 1-4 of *CAD models*).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ._sample_common import _BATCH_CANDIDATES, _CAND, _RADIUS, _Parts, _check_count, _cross, _near, _thin

logger = logging.getLogger(__name__)

_MAX_TILE_CANDIDATES = 2_000_000
_MAX_DEPTH = 14


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
    if not model.faces:
        raise ValueError(f"model {getattr(model, 'source', '')!r} has no faces to sample")
    # the faces of the part: supplemental geometry (Model.supplemental) is never sampled,
    # its points would be surface the manufactured part does not have
    index = model.part_faces() if hasattr(model, "part_faces") else range(len(model.faces))
    faces = tuple(model.faces[i] for i in index)
    h = _CAND * s
    r = _RADIUS * s
    boxes = [_face_box(face) for face in faces]
    metrics = [_metric(face.surface, box) for face, box in zip(faces, boxes)]
    _check_count(sum(mt[-1] for mt in metrics), s)  # before any fine work
    plans = [_plan(face.surface, box, h, metric=mt)[0]
             for face, box, mt in zip(faces, boxes, metrics)]
    parts = _Parts()
    for fi, face, tiles in zip(index, faces, plans):
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
