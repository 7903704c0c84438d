"""Exact ray–CAD intersection (thesis §9.2): seeds from a tessellation, Newton on the NURBS face.

A ray's seed is its first hit on a triangle tessellation of the model (a bounding-volume hierarchy
finds it); the exact intersection then solves ``S(u, v) = o + t d`` by Newton on that face. A
solution outside the face's trimmed domain (a ray through a hole, or past a trimming curve) is
rejected and the search goes on beyond that triangle, so trims are respected exactly.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from shapeverify.camera import _kernels

NEWTON_TOL = 1e-10  # mm: residual |S(u, v) - (o + t d)| at convergence
MAX_RETRIES = 6


@dataclass(frozen=True, eq=False)
class RayHits:
    """First intersection of each ray with the trimmed CAD surface.

    Attributes
    ----------
    hit : (N,) bool
    points : (N, 3) float64, NaN where no hit (mm)
    distances : (N,) float64, ray parameter t (distance for unit directions), inf where no hit
    face : (N,) int64, -1 where no hit
    uv : (N, 2) float64, NaN where no hit
    normals : (N, 3) float64, outward unit normals, NaN where no hit
    """

    hit: np.ndarray
    points: np.ndarray
    distances: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    normals: np.ndarray

    def __repr__(self) -> str:
        return f"RayHits(rays={len(self.hit):,}, hits={int(self.hit.sum()):,})"


class RayScene:
    """A model prepared for ray queries: packed NURBS, a seed tessellation and its BVH."""

    def __init__(self, model, max_edge: float | None = None):
        from shapeverify.cad.nurbs import pack_surfaces
        from shapeverify.cad.tessellate import tessellate_model

        if model.kind != "cad":
            raise ValueError(f"exact ray intersection needs a CAD model (trimmed NURBS faces), got a {model.kind} model")
        if len(model.faces) == 0:
            raise ValueError("the model has no faces to intersect")
        self.model = model
        self.tess = tessellate_model(model, max_edge=max_edge)
        self.packed = pack_surfaces([f.surface for f in model.faces])
        self.pk = self.packed.kernel_args
        self.domains = np.ascontiguousarray(self.packed.domains)
        self.pmax = int(self.packed.degrees[:, 0].max())
        self.qmax = int(self.packed.degrees[:, 1].max())
        v, t = self.tess.vertices, self.tess.triangles
        tv = v[t]
        self.bvh = _kernels.build_bvh(tv.min(axis=1), tv.max(axis=1), tv.mean(axis=1))

    def __repr__(self) -> str:
        return f"RayScene(faces={len(self.model.faces)}, {self.tess!r})"

    # ------------------------------------------------------------------ exact pieces
    def _finish(self, origins, directions, face, uv, t) -> RayHits:
        from shapeverify.cad.nurbs import evaluate_packed

        hit = face >= 0
        n = len(face)
        points = np.full((n, 3), np.nan)
        normals = np.full((n, 3), np.nan)
        if hit.any():
            d = evaluate_packed(self.packed, face[hit], uv[hit], order=1)
            points[hit] = d[:, 0, 0]
            nrm = np.cross(d[:, 1, 0], d[:, 0, 1])
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            flip = np.array([self.model.faces[f].reversed for f in face[hit]])
            nrm[flip] *= -1
            normals[hit] = nrm
        uv = np.where(hit[:, None], uv, np.nan)
        return RayHits(hit, points, np.where(hit, t, np.inf), np.where(hit, face, -1), uv, normals)

    def _check_trims(self, face, uv) -> np.ndarray:
        """Boolean mask: the (face, uv) lies inside its face's trimmed domain."""
        ok = np.zeros(len(face), dtype=bool)
        for f in np.unique(face[face >= 0]):
            sel = face == f
            ok[sel] = self.model.faces[f].contains(uv[sel])
        return ok

    def intersect(self, origins, directions) -> RayHits:
        """First exact hit of every ray (see :func:`intersect_rays`)."""
        o, d = _check_rays(origins, directions)
        n = len(o)
        face = np.full(n, -1, np.int64)
        uv = np.zeros((n, 2))
        t = np.full(n, np.inf)
        tmin = np.zeros(n)
        todo = np.arange(n)
        for _ in range(MAX_RETRIES):
            if len(todo) == 0:
                break
            f_, uv_, t_, tri_ = (np.empty(len(todo), np.int64), np.zeros((len(todo), 2)),
                                 np.zeros(len(todo)), np.empty(len(todo), np.int64))
            _kernels.intersect_many(o[todo], d[todo], tmin[todo], self.tess.vertices, self.tess.triangles,
                                    self.tess.triangle_face, self.tess.uv, self.bvh, self.pk, self.domains,
                                    self.pmax, self.qmax, NEWTON_TOL, f_, uv_, t_, tri_)
            good = f_ >= 0
            if good.any():
                inside = self._check_trims(f_[good], uv_[good])
                idx = np.flatnonzero(good)
                f_[idx[~inside]] = -2  # outside the trims: look beyond
            accept = f_ >= 0
            face[todo[accept]] = f_[accept]
            uv[todo[accept]] = uv_[accept]
            t[todo[accept]] = t_[accept]
            retry = f_ == -2
            # continue the search just beyond the rejected seed triangle
            tmin[todo[retry]] = np.maximum(t_[retry], tmin[todo[retry]]) + 1e-9 * (1 + np.abs(t_[retry]))
            todo = todo[retry]
        return self._finish(o, d, face, uv, t)


def _check_rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = np.ascontiguousarray(np.asarray(origins, dtype=np.float64))
    d = np.asarray(directions, dtype=np.float64)
    if o.ndim != 2 or o.shape[1] != 3:
        raise ValueError(f"origins must have shape (N, 3), got {o.shape}")
    if d.shape != o.shape:
        raise ValueError(f"directions must have the shape of origins {o.shape}, got {d.shape}")
    if not (np.all(np.isfinite(o)) and np.all(np.isfinite(d))):
        raise ValueError("origins and directions must be finite (no NaN or inf)")
    norm = np.linalg.norm(d, axis=1)
    if np.any(norm == 0):
        raise ValueError(f"{int((norm == 0).sum())} ray direction(s) are zero vectors")
    return o, np.ascontiguousarray(d / norm[:, None])


_SCENES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def scene_for(model_or_prep) -> RayScene:
    """The (cached) RayScene of a Model or Prepared model."""
    if isinstance(model_or_prep, RayScene):
        return model_or_prep
    model = getattr(model_or_prep, "model", model_or_prep)
    scene = _SCENES.get(model)
    if scene is None:
        scene = RayScene(model)
        _SCENES[model] = scene
    return scene


def intersect_rays(prep, origins, directions) -> RayHits:
    """First exact intersection of each ray with the trimmed CAD surface.

    Parameters
    ----------
    prep : Prepared, Model or RayScene
        The CAD model (the ray scene is built once per model and cached).
    origins, directions : (N, 3) float64
        Rays ``o + t d`` with t > 0; directions need not be unit (they are normalised, so
        ``distances`` are Euclidean).

    Returns
    -------
    RayHits

    References
    ----------
    Bergström 2011, thesis §9.2 (line intersections); Paper IV.
    """
    return scene_for(prep).intersect(origins, directions)
