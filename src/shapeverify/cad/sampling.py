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
of the 12 nearest thinned points, oriented consistently along the neighbour graph from the
point that faces most clearly away from the cloud's centroid (outward for closed parts and
single scanner views of convex parts; one consistent side for a sheet).  Then the thinning at ``0.85 * spacing`` with normals (random
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
from shapeverify._lazy import cKDTree

from .._random import generator
# the samplers of each model kind, and what they share; the private names stay importable from here
from ._sample_cloud import _any_tangent, _neighbour_cov, _pca_normals, _sample_cloud  # noqa: F401
from ._sample_common import (  # noqa: F401
    _BATCH_CANDIDATES, _CAND, _COS_SAME_SIDE, _RADIUS, MAX_POINTS, _check_count, _cross, _hash_slot,
    _near, _Parts, _thin, _thin_kernel)
from ._sample_faces import (  # noqa: F401
    _MAX_DEPTH, _MAX_TILE_CANDIDATES, _arc_params, _cad_batch, _cad_free_edge_flags, _face_box, _metric,
    _n_coarse, _plan, _sample_cad, _tile_grid)
from ._sample_mesh import _lattice_count_fill, _mesh_free_edge_flags, _mesh_free_edges, _sample_mesh  # noqa: F401

__all__ = ["sample_model", "half_extents_from_graph", "needed_spacing", "MAX_POINTS",
           "CAD_TARGET_POINTS", "CAD_MAX_COARSENING"]

logger = logging.getLogger(__name__)


# ----------------------------------------------------------------------------------- public
def sample_model(model, spacing, rng=None, *, half_extents=True):
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
    half_extents : bool
        False: ``half_extent`` is left at ``spacing`` (a placeholder), for a caller that
        measures it later from its own neighbour graph (:func:`half_extents_from_graph`, as
        ``prepare`` does: it needs the graph anyway, and the kd-tree search here is a quarter
        of the sampling time at 1M points).

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
    rng = generator(rng)
    kind = getattr(model, "kind", "cad")
    if kind == "cad":
        parts = _sample_cad(model, s, rng)
    elif kind == "mesh":
        parts = _sample_mesh(model, s, rng)
    elif kind == "points":
        parts = _sample_cloud(model, s, rng)
    else:
        raise ValueError(f"model.kind must be 'cad', 'mesh' or 'points', got {kind!r}")
    return _finish(parts, s, model, half_extents)


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
    * CAD: the spacing that gives about :data:`CAD_TARGET_POINTS` model points, at most
      :data:`CAD_MAX_COARSENING` times ``size / 500`` and at most the thinnest wall or gap
      over :data:`CAD_SPACINGS_PER_WALL`; 0 when ``size / 500`` gives fewer points.  A sheet
      (area about 0.5 size**2) has about 1.2e5 model points at ``size / 500`` and keeps it; a
      solid part (area 1.5-2 size**2: the wavy cube, a turned part) had 3.7-4.4e5, and its
      preparation cost followed them (19-28 s CPU for a 15-face turned part, 5-6 s now).  The
      cap on the coarsening bounds the price: the fast answers' tangent-patch error grows with
      the square of the spacing, so it is at most 4x that of ``size / 500`` (the exact
      answers, which the deviations use, are exact at any spacing; measured on a turned part
      with 0.013 mm scan noise, the mean deviation moved by 0.3-1.0 um).  Thin walls keep
      their spacing: the impeller's 0.6 mm blades stop its coarsening (at 0.49 mm spacing 4 of
      24 perturbed starts ended on the wrong side of a blade).  The count and the walls are
      measured on a sampling at 4 x ``size / 500`` (1/16 of the points; 0.2-0.9 s).

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
    return _cad_spacing(model)


_MESH_MIN_POINTS = 10_000
_MESH_POINTS_PER_TRIANGLE = 4
#: the model point count ``prepare``'s default spacing aims at for a CAD model (see needed_spacing)
CAD_TARGET_POINTS = 150_000
#: ... never coarser than this times ``size / 500`` (tangent-patch error at most 4x)
CAD_MAX_COARSENING = 2.0
_CAD_PROBE = 4.0  # the count is estimated at this times size / 500
#: ... and never coarser than the thinnest wall (or gap) over this number (see _wall_thickness)
CAD_SPACINGS_PER_WALL = 2.5


def _cad_spacing(model) -> float:
    """The CAD part of :func:`needed_spacing`: about CAD_TARGET_POINTS model points."""
    size = float(model.size)
    if not model.faces or not size > 0:
        return 0.0
    base = size / 500.0
    probe = _CAD_PROBE * base
    P, N = _sample_cad(model, probe, None)[:2]
    factor = min(math.sqrt(len(P) * _CAD_PROBE ** 2 / CAD_TARGET_POINTS), CAD_MAX_COARSENING)
    if factor <= 1.0:
        return 0.0
    wall = _wall_thickness(P, N, probe, CAD_SPACINGS_PER_WALL * factor * base)
    factor = min(factor, wall / CAD_SPACINGS_PER_WALL / base)
    return base * factor if factor > 1.0 else 0.0


def _wall_thickness(P, N, probe, upto, share=0.05):
    """The thickness of the thinnest walls or gaps (mm) that ``share`` of the points sees,
    up to ``upto``: for each point, the nearest point facing the other way (normals more than
    120 degrees apart) about straight across (sideways at most 0.75 probe spacings), measured
    along the normal; ``upto`` when fewer than ``share`` of the points have one.

    The impeller's 0.6 mm blades give 0.28 mm (its blade edges, where the skins meet, count
    too); at spacings near a wall's thickness the nearest model point of a query lies on the
    wall's other skin, and registration locked onto the wrong side of the blades (measured:
    the impeller at 0.49 mm spacing, 4 of 24 perturbed starts wrong and converged).
    """
    radius = math.hypot(upto, 0.75 * probe)
    d, j = cKDTree(P).query(P, k=24, distance_upper_bound=radius)
    ok = np.isfinite(d)
    j = np.where(ok, j, 0)
    D = P[j] - P[:, None, :]
    along = np.abs(np.einsum("ikj,ij->ik", D, N))
    side = np.sqrt(np.maximum(np.where(ok, d, 0.0) ** 2 - along ** 2, 0.0))
    facing = ok & (np.einsum("ikj,ij->ik", N[j], N) < -0.5) & (side <= 0.75 * probe)
    t = np.where(facing, along, upto).min(axis=1)
    return float(min(np.quantile(t, share), upto))


# ---------------------------------------------------------------------------------- finish
def _finish(parts, s, model, half_extents=True):
    from shapeverify.cad.model import ModelPoints

    P, N, T, F, UV, boundary = parts
    if len(P) == 0:
        raise ValueError(f"sampling {getattr(model, 'source', 'the model')!r} at spacing {s} "
                         "produced no points (all faces trimmed away or degenerate)")
    # orthonormal frame: t_u = Su direction projected into the tangent plane, t_v = n x t_u
    T = T - np.einsum("ij,ij->i", T, N)[:, None] * N
    T /= np.linalg.norm(T, axis=1)[:, None]
    Tv = _cross(N, T)
    half = _half_extents(P, T, Tv, s) if half_extents else np.full((len(P), 2), s)
    return ModelPoints(points=P, normals=N, face=F.astype(np.int32), uv=UV, tangent_u=T,
                       tangent_v=Tv, half_extent=half, boundary=boundary, spacing=s)


@njit(cache=True, nogil=True)
def _max_projections(P, nb, Tu, Tv, out, c0=1):
    """out[i] = max over neighbours j = nb[i, c0:] (-1: none) of |(P_j - P_i) . Tu_i|,
    |(P_j - P_i) . Tv_i|."""
    for i in range(P.shape[0]):
        mu = 0.0
        mv = 0.0
        for c in range(c0, nb.shape[1]):
            j = nb[i, c]
            if j < 0:
                continue
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


def half_extents_from_graph(P, Tu, Tv, s, graph, k=6):
    """``half_extent`` (N, 2) of model points ``P`` with tangents ``Tu``, ``Tv`` from their
    neighbour graph (N, >= k) int32 (other points nearest first, -1 where missing; e.g.
    :func:`shapeverify.nearest.dvg.neighbor_graph`): the rule of :func:`sample_model` on the
    first ``k`` neighbours.  The same values as the sampling's own kd-tree search wherever
    the k nearest are the same points (they can differ only at exact distance ties)."""
    n = len(P)
    if n <= 1:
        return np.full((n, 2), s)
    proj = np.empty((n, 2))
    _max_projections(np.ascontiguousarray(P), np.ascontiguousarray(graph[:, :k]),
                     np.ascontiguousarray(Tu), np.ascontiguousarray(Tv), proj, 0)
    return np.clip(0.6 * proj, 0.5 * s, 1.5 * s)


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
