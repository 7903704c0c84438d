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

from shapeverify._arrays import check_points
from shapeverify.camera import _kernels

NEWTON_TOL = 1e-10  # mm: residual |S(u, v) - (o + t d)| at convergence
BARY_TOL = 0.05  # seed triangles are widened by 5 % so that rays through a chordal gap still get a seed


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
    derivatives : (N, 6) float64, Su and Sv at the hit (used by the small-motion update)
    """

    hit: np.ndarray
    points: np.ndarray
    distances: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    normals: np.ndarray
    derivatives: np.ndarray

    def __repr__(self) -> str:
        return f"RayHits(rays={len(self.hit):,}, hits={int(self.hit.sum()):,})"


class RayScene:
    """A model prepared for ray queries: packed NURBS, a seed tessellation and its BVH."""

    def __init__(self, model, max_edge: float | None = None):
        from shapeverify.cad.nurbs import pack_surfaces
        from shapeverify.cad.tessellate import tessellate_model
        from shapeverify.cad.trim import loop_segments, pack_trims

        if model.kind != "cad":
            raise ValueError(f"exact ray intersection needs a CAD model (trimmed NURBS faces), got a {model.kind} model")
        if len(model.faces) == 0:
            raise ValueError("the model has no faces to intersect")
        self.model = model
        self.max_edge = model.size / 200.0 if max_edge is None else float(max_edge)
        self.tess = tessellate_model(model, max_edge=self.max_edge)
        self.trims = pack_trims([loop_segments(f.loops) for f in model.faces])
        self.packed = pack_surfaces([f.surface for f in model.faces])
        self.pk = self.packed.kernel_args
        self.domains = np.ascontiguousarray(self.packed.domains)
        self.reversed = np.array([f.reversed for f in model.faces], dtype=bool)
        self.pmax = int(self.packed.degrees[:, 0].max())
        self.qmax = int(self.packed.degrees[:, 1].max())
        v, t = self.tess.vertices, self.tess.triangles
        tv = v[t]
        self.bvh = _kernels.build_bvh(tv.min(axis=1), tv.max(axis=1), tv.mean(axis=1))

    def __repr__(self) -> str:
        return f"RayScene(faces={len(self.model.faces)}, {self.tess!r})"

    # ------------------------------------------------------------------ exact pieces
    def _finish(self, face, uv, t, pn) -> RayHits:
        """Assemble RayHits from kernel outputs; pn (N, 12) holds point, unit Su x Sv, Su, Sv."""
        n = len(face)
        points, normals, uv_out = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2))
        t_out, face_out, deriv = np.empty(n), np.empty(n, np.int64), np.empty((n, 6))
        _kernels.finish(np.ascontiguousarray(face, dtype=np.int64), np.ascontiguousarray(uv),
                        np.ascontiguousarray(t, dtype=np.float64), np.ascontiguousarray(pn), self.reversed,
                        points, normals, uv_out, t_out, face_out, deriv)
        return RayHits(face_out >= 0, points, t_out, face_out, uv_out, normals, deriv)

    def intersect(self, origins, directions) -> RayHits:
        """First exact hit of every ray (see :func:`intersect_rays`)."""
        o, d = _check_rays(origins, directions)
        return self._intersect(o, d)

    def _intersect(self, o, d) -> RayHits:
        n = len(o)
        face = np.empty(n, np.int64)
        uv = np.zeros((n, 2))
        t = np.full(n, np.inf)
        pn = np.zeros((n, 12))
        _kernels.intersect_many(o, d, np.zeros(n), self.tess.vertices, self.tess.triangles,
                                self.tess.triangle_face, self.tess.uv, self.bvh, self.pk, self.domains,
                                self.trims, self.pmax, self.qmax, NEWTON_TOL, 0.5 * self.max_edge,
                                BARY_TOL, face, uv, t, pn)
        return self._finish(face, uv, t, pn)


def _check_rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = check_points(origins, "origins", single=False)
    d = np.asarray(directions, dtype=np.float64)
    if d.shape != o.shape:
        raise ValueError(f"directions must have the shape of origins {o.shape}, got {d.shape}")
    d = check_points(d, "directions", single=False)
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
