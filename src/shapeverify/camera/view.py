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
from scipy.ndimage import binary_dilation

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


def _rays_in_model(T_world_model: np.ndarray, rays):
    """The camera's pixel rays (world frame, from ``camera.pixel_rays()``) in model coordinates."""
    o, d = rays
    Tinv = np.linalg.inv(T_world_model)
    R, t = Tinv[:3, :3], Tinv[:3, 3]
    o_model = np.empty_like(o)
    o_model[:] = R @ o[0] + t  # every pixel ray starts at the projection centre
    return o_model, np.ascontiguousarray(d @ R.T)


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
    rays_world: tuple = None
    seeds: tuple = None  # (uv (N, 2), t (N,), stored (N, 12)) packed once for depth_map

    def __repr__(self) -> str:
        return f"View({self.camera.width}x{self.camera.height}, hits={int(self.hits.hit.sum()):,})"

    def images(self) -> dict:
        """Depth (camera z, mm), normal (world), face id and hit-mask images of this view."""
        return render_images(self.camera, self.hits, self.T_world_model)


def _unstable_pixels(hits: RayHits, directions: np.ndarray, shape, footprint: np.ndarray) -> np.ndarray:
    """Pixels where occlusion may change under a small motion.

    A pixel is unstable when a 4-neighbour differs in hit/miss, when the neighbour's depth is not
    continued by this pixel's tangent plane (an occlusion edge: the predicted depth along the
    neighbour's ray misses the stored one by more than two pixel footprints), or at grazing
    incidence (|cos| < 0.1).
    """
    H, W = shape
    hit = hits.hit.reshape(H, W)
    t = np.where(hits.hit, hits.distances, 0.0).reshape(H, W)
    d = directions.reshape(H, W, 3)
    n = np.where(hits.hit[:, None], hits.normals, 0.0).reshape(H, W, 3)
    fp = footprint.reshape(H, W)
    cos = np.abs(np.einsum("ijk,ijk->ij", d, n))
    un = hit & (cos < 0.1)
    for axis in (0, 1):
        a = tuple(slice(0, -1) if k == axis else slice(None) for k in (0, 1))
        b = tuple(slice(1, None) if k == axis else slice(None) for k in (0, 1))
        edge = hit[a] != hit[b]
        both = hit[a] & hit[b]
        with np.errstate(divide="ignore", invalid="ignore"):
            # depth along b's ray predicted by a's tangent plane, and vice versa
            num_a = t[a] * np.einsum("ijk,ijk->ij", d[a], n[a])
            pred_b = num_a / np.einsum("ijk,ijk->ij", d[b], n[a])
            num_b = t[b] * np.einsum("ijk,ijk->ij", d[b], n[b])
            pred_a = num_b / np.einsum("ijk,ijk->ij", d[a], n[b])
            tol = 2.0 * np.maximum(fp[a], fp[b])
            jump = both & ~((np.abs(pred_b - t[b]) <= tol) & (np.abs(pred_a - t[a]) <= tol))
        edge |= jump
        un[a] |= edge
        un[b] |= edge
    return un.ravel()


def make_view(prep, camera: PinholeCamera, T_world_model=None) -> View:
    """Intersect every pixel ray with the model at pose ``T_world_model`` (default identity)."""
    scene = scene_for(prep)
    T = np.eye(4) if T_world_model is None else _rigid(T_world_model, "T_world_model")
    rays_world = camera.pixel_rays()
    o, d = _rays_in_model(T, rays_world)
    hits = scene.intersect(o, d)
    footprint = np.where(hits.hit, hits.distances, 0.0) / min(camera.fx, camera.fy)
    unstable = _unstable_pixels(hits, d, (camera.height, camera.width), footprint)
    n = len(hits.hit)
    stored = np.zeros((n, 12))
    stored[:, :3] = np.where(hits.hit[:, None], hits.points, 0.0)
    stored[:, 6:] = hits.derivatives
    seeds = (np.ascontiguousarray(np.where(hits.hit[:, None], hits.uv, 0.0)),
             np.where(hits.hit, hits.distances, 0.0), stored)
    return View(scene, camera, T, hits, unstable, rays_world, seeds)


def _motion_pixels(view: View, T: np.ndarray) -> float:
    """Largest image displacement (pixels) of the model's bounding-box corners under T."""
    lo, hi = view.scene.model.bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    Tv = view.T_world_model
    before = corners @ Tv[:3, :3].T + Tv[:3, 3]
    after = before @ T[:3, :3].T + T[:3, 3]
    p0, z0 = view.camera.project(before)
    p1, z1 = view.camera.project(after)
    if np.any(z0 <= 0) or np.any(z1 <= 0):
        return float(max(view.camera.width, view.camera.height))
    return float(np.max(np.linalg.norm(p1 - p0, axis=1)))


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
    o, d = _rays_in_model(T_new, view.rays_world)
    h = view.hits
    n = len(h.hit)
    ok = np.zeros(n, dtype=bool)
    uv = np.zeros((n, 2))
    t = np.zeros(n)
    pn = np.zeros((n, 12))
    # occlusion can change only near the stored view's discontinuities, within the motion's reach
    reach = int(np.ceil(_motion_pixels(view, T))) + 1
    H, W = view.camera.height, view.camera.width
    if reach >= max(H, W):
        unstable = np.ones(n, dtype=bool)
    else:
        unstable = binary_dilation(view.unstable.reshape(H, W), iterations=reach).ravel()
    faces = np.where(h.hit & ~unstable, h.face, -1).astype(np.int64)
    seed_uv, seed_t, stored = view.seeds
    _kernels.update_many(o, d, faces, seed_uv, seed_t, stored, scene.pk, scene.domains,
                         scene.trims, scene.pmax, scene.qmax, NEWTON_TOL, ok, uv, t, pn)
    face = np.where(ok, faces, -1)
    t = np.where(ok, t, np.inf)
    # recompute: failed seeds and pixels on a stored discontinuity; other stored misses stay misses
    redo = np.flatnonzero((h.hit & ~ok) | unstable)
    if len(redo):
        fresh = scene._intersect(o[redo], d[redo])
        face[redo] = fresh.face
        uv[redo] = np.where(fresh.hit[:, None], fresh.uv, 0.0)
        t[redo] = fresh.distances
        pn[redo, :3] = fresh.points
        pn[redo, 3:6] = fresh.normals * np.where(scene.reversed[np.maximum(fresh.face, 0)], -1.0, 1.0)[:, None]
        pn[redo, 6:] = fresh.derivatives
    return scene._finish(face, uv, t, pn)


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
