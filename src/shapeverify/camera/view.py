"""Pre-processed views (Paper IV) and renders of the CAD model seen by a camera.

A :class:`View` stores, for a fixed camera and part pose, the face and (u, v, t) of every pixel's
hit. :func:`depth_map` recomputes the exact hits after the part moves by a small rigid motion
``T`` starting from those seeds (a few Newton steps per pixel), and recomputes from scratch only
the pixels whose seed fails: Newton does not converge, the hit leaves its face's trimmed domain,
or the pixel lies on a depth or face discontinuity of the stored view (where occlusion may change).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shapeverify.camera import _kernels
from shapeverify.camera.intersect import NEWTON_TOL, RayHits, RayScene, scene_for
from shapeverify.camera.pinhole import PinholeCamera


def _rigid(T, name="T") -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{name} must be a finite (4, 4) rigid transform, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-8) or np.linalg.det(R) < 0:
        raise ValueError(f"{name}[:3, :3] must be a rotation (orthonormal, det +1)")
    return T


def _rays_in_model(camera: PinholeCamera, T_world_model: np.ndarray):
    """All pixel rays of the camera expressed in model coordinates."""
    o, d = camera.pixel_rays()
    Tinv = np.linalg.inv(T_world_model)
    R, t = Tinv[:3, :3], Tinv[:3, 3]
    return np.ascontiguousarray(o @ R.T + t), np.ascontiguousarray(d @ R.T)


@dataclass(frozen=True, eq=False)
class View:
    """Per-pixel exact hits of the CAD model for one camera and part pose.

    Attributes
    ----------
    camera : PinholeCamera
    T_world_model : (4, 4) pose of the part in the world (camera) frame
    hits : RayHits, row-major over the image (height * width)
    unstable : (H*W,) bool, pixels on a face or depth discontinuity (recomputed on update)
    """

    scene: RayScene
    camera: PinholeCamera
    T_world_model: np.ndarray
    hits: RayHits
    unstable: np.ndarray

    def __repr__(self) -> str:
        return f"View({self.camera.width}x{self.camera.height}, hits={int(self.hits.hit.sum()):,})"

    def images(self) -> dict:
        """Depth (camera z, mm), normal (world), face id and hit-mask images of this view."""
        return render_images(self.camera, self.hits, self.T_world_model)


def _unstable_pixels(hits: RayHits, shape, depth_jump: float) -> np.ndarray:
    face = hits.face.reshape(shape)
    t = np.where(hits.hit, hits.distances, np.inf).reshape(shape)
    un = np.zeros(shape, dtype=bool)
    for axis in (0, 1):
        df = np.diff(face, axis=axis) != 0
        with np.errstate(invalid="ignore"):
            dt = ~(np.abs(np.diff(t, axis=axis)) <= depth_jump)
        edge = df | dt
        sl_a = [slice(None), slice(None)]
        sl_b = [slice(None), slice(None)]
        sl_a[axis] = slice(0, -1)
        sl_b[axis] = slice(1, None)
        un[tuple(sl_a)] |= edge
        un[tuple(sl_b)] |= edge
    return un.ravel()


def make_view(prep, camera: PinholeCamera, T_world_model=None, depth_jump: float | None = None) -> View:
    """Intersect every pixel ray with the model at pose ``T_world_model`` (default identity).

    ``depth_jump`` (mm) marks neighbouring pixels whose depths differ more than this as a
    discontinuity (default: 20 times the pixel footprint at the median depth).
    """
    scene = scene_for(prep)
    T = np.eye(4) if T_world_model is None else _rigid(T_world_model, "T_world_model")
    o, d = _rays_in_model(camera, T)
    hits = scene.intersect(o, d)
    if depth_jump is None:
        med = np.median(hits.distances[hits.hit]) if hits.hit.any() else 1.0
        depth_jump = 20.0 * med / camera.fx
    unstable = _unstable_pixels(hits, (camera.height, camera.width), depth_jump)
    return View(scene, camera, T, hits, unstable)


def depth_map(view: View, T) -> RayHits:
    """Exact hits after the part moves by the small rigid motion ``T`` (new pose = T @ view pose).

    Stored seeds are refined by Newton; pixels whose seed fails (no convergence, outside the trims,
    on a stored discontinuity, or a stored miss next to a hit) are recomputed from scratch.

    Returns
    -------
    RayHits in the moved model's coordinates (points, normals), row-major over the image.
    """
    T = _rigid(T)
    scene = view.scene
    T_new = T @ view.T_world_model
    o, d = _rays_in_model(view.camera, T_new)
    h = view.hits
    n = len(h.hit)
    ok = np.zeros(n, dtype=bool)
    uv = np.zeros((n, 2))
    t = np.zeros(n)
    faces = np.where(h.hit & ~view.unstable, h.face, -1).astype(np.int64)
    seed_uv = np.where(h.hit[:, None], h.uv, 0.0)
    seed_t = np.where(h.hit, h.distances, 0.0)
    _kernels.update_many(o, d, faces, np.ascontiguousarray(seed_uv), seed_t, scene.pk, scene.domains,
                         scene.pmax, scene.qmax, NEWTON_TOL, ok, uv, t)
    idx = np.flatnonzero(ok)
    if len(idx):
        inside = scene._check_trims(faces[idx], uv[idx])
        ok[idx[~inside]] = False
    face = np.where(ok, faces, -1)
    # recompute: failed seeds, unstable pixels; stored misses stay misses unless unstable
    redo = (h.hit & ~ok) | view.unstable
    if redo.any():
        fresh = scene.intersect(o[redo], d[redo])
        face[redo] = fresh.face
        uv[redo] = np.where(fresh.hit[:, None], fresh.uv, 0.0)
        t[redo] = fresh.distances
    return scene._finish(o, d, face, uv, np.where(face >= 0, t, np.inf))


def render_images(camera: PinholeCamera, hits: RayHits, T_world_model=None) -> dict:
    """Images (height, width) from per-pixel hits: ``depth`` (camera z, mm, NaN where no hit),
    ``normal`` (H, W, 3) in world coordinates, ``face`` (-1 where no hit) and ``mask``."""
    H, W = camera.height, camera.width
    T = np.eye(4) if T_world_model is None else np.asarray(T_world_model, dtype=np.float64)
    pts_w = np.where(hits.hit[:, None], hits.points, 0.0) @ T[:3, :3].T + T[:3, 3]
    z = camera.to_camera(pts_w)[:, 2]
    depth = np.where(hits.hit, z, np.nan).reshape(H, W)
    normal = (np.where(hits.hit[:, None], hits.normals, np.nan) @ T[:3, :3].T).reshape(H, W, 3)
    return {"depth": depth, "normal": normal, "face": hits.face.reshape(H, W), "mask": hits.hit.reshape(H, W)}


def render(prep, camera: PinholeCamera, T_world_model=None) -> dict:
    """Depth, normal, face-id and hit-mask images of the CAD model seen by ``camera``."""
    return make_view(prep, camera, T_world_model).images()
