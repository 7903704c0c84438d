"""Exact simulation of the fringe images a two-camera rig records (thesis §3.1, Paper III).

For every camera pixel: the exact first hit of its ray on the trimmed CAD surface
(:func:`shapeverify.camera.intersect_rays`), optionally displaced by a smooth dent; the projector
pixel of the hit and the pattern there (``(1 + cos(2 pi u / period_px)) / 2``, see
:mod:`shapeverify.camera.rig`); a projector shadow test (the ray from the hit towards the projector
centre intersected with the model); Lambertian shading ``max(0, n . l)`` (zero when camera and
projector are on opposite sides of the sheet); ambient light; optional specular reflection spots;
Gaussian camera noise; 8- or 16-bit quantisation with saturation.  The truth (surface point of each
pixel, masks) comes along for tests and benchmarks.

Pixels are point-sampled at their centres (``supersample=1``) or averaged over an s x s grid of
sub-pixel rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._random import generator
from shapeverify._renamed import grouped_keywords

__all__ = ["CameraResponse", "FringeImages", "fringe_images", "demo_scene"]


@dataclass(frozen=True, repr=False)
class FringeImages:
    """Simulated fringe images and their truth.

    Attributes
    ----------
    left, right : (H, W) uint8 or uint16
        The recorded images.
    rig : Rig
        The rig used (its pattern period is the one rendered).
    T_left_model : (4, 4) float64
        Pose of the model in the left camera frame.
    truth : dict
        Per camera (``"left"``, ``"right"``): ``points`` (H, W, 3) true surface point (left frame,
        with the dent; NaN where no hit), ``hit``, ``lit`` (hit, inside the projector image, not
        in shadow, facing both camera and projector), ``reflection`` (near a reflection spot),
        ``saturated``, ``dent`` (on the dent) -- all (H, W) bool.
    dent : tuple or None
        (center (3,) model frame, depth mm, radius mm) of the dent.
    """

    left: np.ndarray
    right: np.ndarray
    rig: object
    T_left_model: np.ndarray
    truth: dict
    dent: tuple | None = None

    def __repr__(self):
        lit = {k: f"{v['lit'].mean():.0%}" for k, v in self.truth.items()}
        return f"FringeImages({self.left.shape[1]}x{self.left.shape[0]}, lit={lit}, {self.rig!r})"


def _to_model(T_left_model, o, d):
    R, t = T_left_model[:3, :3], T_left_model[:3, 3]
    return np.ascontiguousarray((o - t) @ R), np.ascontiguousarray(d @ R)


def _apply_dent(points, normals, dirs, dent):
    """Move hits onto the dented surface ``depth (1 - (s/r)^2)^2`` inside along -normal (a few fixed-point steps)."""
    c, depth, radius = dent
    X = points.copy()
    on = np.zeros(len(X), bool)
    cos = np.einsum("ij,ij->i", dirs, normals)
    for _ in range(4):
        s2 = ((X - c) ** 2).sum(axis=1) - (((X - c) * normals).sum(axis=1)) ** 2
        h = np.where(s2 < radius * radius, depth * (1 - s2 / radius ** 2) ** 2, 0.0)
        # offset of X below the CAD tangent plane must equal h: solve along the ray
        off = -((X - points) * normals).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            dt = np.where(np.abs(cos) > 1e-3, (h - off) / -cos, 0.0)
        X = X + dt[:, None] * dirs
        on = h > 0
    return X, on


def _spots(points, reflections):
    """Intensity added by specular spots (Gaussian in distance, model frame) and the affected mask."""
    add = np.zeros(len(points))
    near = np.zeros(len(points), bool)
    for c, radius, peak in reflections:
        d2 = ((points - np.asarray(c, float)) ** 2).sum(axis=1)
        add += peak * np.exp(-d2 / radius ** 2)
        near |= d2 < (2.5 * radius) ** 2
    return add, near


def _render_camera(scene, rig, dev, T, pattern_period, rows, dent, reflections, ambient, gain, ss, offset=0.0):
    from shapeverify.camera.intersect import intersect_rays

    H, W = dev.height, dev.width
    base = dev.pixel_grid()
    offs = [((i + 0.5) / ss - 0.5, (j + 0.5) / ss - 0.5) for i in range(ss) for j in range(ss)]
    acc = np.zeros(H * W)
    truth = None
    proj = rig.projector
    pc_model = _to_model(T, proj.center[None], np.zeros((1, 3)))[0][0]
    for k, (du, dv) in enumerate(offs):
        o, d = dev.rays(base + np.array([du, dv]))
        om, dm = _to_model(T, o, d)
        hits = intersect_rays(scene, om, dm)
        hit = hits.hit
        X = np.where(hit[:, None], hits.points, 0.0)
        n = np.where(hit[:, None], hits.normals, 0.0)
        on_dent = np.zeros(len(X), bool)
        if dent is not None:
            Xd, on_dent = _apply_dent(X, n, dm, dent)
            on_dent &= hit
        else:
            Xd = X
        Xl = Xd @ T[:3, :3].T + T[:3, 3]
        uvp, zp = proj.project(Xl)
        coord = uvp[:, 1] if rows else uvp[:, 0]
        inside = (zp > 0) & (uvp[:, 0] >= -0.5) & (uvp[:, 0] <= proj.width - 0.5) & \
                 (uvp[:, 1] >= -0.5) & (uvp[:, 1] <= proj.height - 0.5)
        to_p = pc_model - X
        dist_p = np.linalg.norm(to_p, axis=1)
        lvec = to_p / np.maximum(dist_p, 1e-12)[:, None]
        ndl = np.einsum("ij,ij->i", n, lvec)
        ndv = -np.einsum("ij,ij->i", n, dm)
        facing = hit & inside & (ndl * ndv > 0)
        # shadow rays from just off the CAD surface, towards the projector
        idx = np.flatnonzero(facing)
        shadow = np.zeros(len(X), bool)
        if len(idx):
            start = X[idx] + 1e-3 * np.sign(ndl[idx])[:, None] * n[idx]
            sh = intersect_rays(scene, start, lvec[idx])
            shadow[idx] = sh.hit & (sh.distances < dist_p[idx] - 1e-2)
        lit = facing & ~shadow
        pattern = 0.5 * (1.0 + np.cos(2 * np.pi * np.where(lit, coord, 0.0) / pattern_period + offset))
        inten = gain * (ambient + np.where(lit, pattern * np.abs(ndl), 0.0))
        inten = np.where(hit, inten, 0.0)
        spot_add, near = _spots(Xd, reflections) if reflections else (0.0, np.zeros(len(X), bool))
        inten = inten + np.where(hit & lit, spot_add, 0.0)
        acc += inten
        if k == 0 or ss == 1:
            truth = dict(points=np.where(hit[:, None], Xl, np.nan).reshape(H, W, 3), hit=hit.reshape(H, W),
                         lit=lit.reshape(H, W), reflection=(near & hit).reshape(H, W),
                         dent=on_dent.reshape(H, W))
    if ss > 1:  # the truth of the pixel centre
        o, d = dev.rays(base)
        om, dm = _to_model(T, o, d)
        hits = intersect_rays(scene, om, dm)
        X = np.where(hits.hit[:, None], hits.points, 0.0)
        if dent is not None:
            X, _ = _apply_dent(X, np.where(hits.hit[:, None], hits.normals, 0.0), dm, dent)
        truth["points"] = np.where(hits.hit[:, None], X @ T[:3, :3].T + T[:3, 3], np.nan).reshape(H, W, 3)
    return (acc / len(offs)).reshape(H, W), truth


@dataclass(frozen=True)
class CameraResponse:
    """How the cameras of :func:`fringe_images` respond (its ``response=``; the loose keywords
    of these names still work, with a DeprecationWarning)."""

    ambient: float = 0.08
    gain: float = 200.0
    bits: int = 8
    supersample: int = 1


@grouped_keywords("response", CameraResponse)
def fringe_images(model, rig, T_left_model=None, period_mm=None, noise=1.0, rng=None, dent=None,
                  reflections=(), phase_offset=0.0,
                  response: CameraResponse = CameraResponse()) -> FringeImages:
    """Render what the two cameras of ``rig`` record of ``model`` lit by one fringe pattern.

    Parameters
    ----------
    model : Model, Prepared or RayScene
        A CAD model (trimmed NURBS faces).
    rig : Rig
        Cameras and projector (:mod:`shapeverify.camera.rig`).
    T_left_model : (4, 4) or None
        Pose of the model in the left camera frame (default identity).
    period_mm : float or None
        Fringe period on the part (mm) at the model's centre: sets the pattern's ``period_px``
        (the rig's own value when None).
    noise : float
        Standard deviation of the additive Gaussian camera noise (grey levels of the output).
    rng : int or Generator or None
        Noise seed (default 0: identical images every run).
    dent : (center (3,), depth, radius) or None
        A smooth dent ``depth (1 - (s/radius)^2)^2`` (mm, > 0 into the material) around the model
        point ``center`` (model frame).
    reflections : sequence of (center (3,), radius, peak)
        Specular spots: ``peak * exp(-s^2/radius^2)`` grey levels (before clipping) added around
        model points ``center`` (mm).
    response : CameraResponse
        Groups ``ambient``, ``gain``, ``bits``, ``supersample`` (described below); the
        loose keywords still work, with a DeprecationWarning.
    ambient : float
        Ambient light, as a fraction of the projector's full intensity.
    gain : float
        Grey level of a surface facing the projector under full projector intensity.
    bits : 8 or 16
        Output depth; 16-bit images are scaled by 257 (full scale 65535).
    supersample : int
        Rays per pixel side (1 = pixel centres only).
    phase_offset : float
        Added to the pattern phase (radians): 0 renders the rig's documented pattern; other values
        model a projector whose phase origin differs (e.g. -pi/2 for a sine pattern).

    Returns
    -------
    FringeImages
    """
    ambient = response.ambient
    gain = response.gain
    bits = response.bits
    supersample = response.supersample
    from shapeverify.camera.intersect import scene_for

    if rig.projector is None:
        raise ValueError("the rig has no projector: fringe images need one (projector key of rig.json)")
    if bits not in (8, 16):
        raise ValueError(f"bits must be 8 or 16, got {bits}")
    if not noise >= 0:
        raise ValueError(f"noise must be >= 0 (grey levels), got {noise}")
    ss = int(supersample)
    if ss < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    scene = scene_for(model)
    T = np.eye(4) if T_left_model is None else np.asarray(T_left_model, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"T_left_model must be a (4, 4) matrix, got {T.shape}")
    rows = rig.pattern.direction == "rows"
    if period_mm is not None:
        if not period_mm > 0:
            raise ValueError(f"period_mm must be positive, got {period_mm}")
        lo, hi = scene.model.bounds
        c = T[:3, :3] @ (0.5 * (lo + hi)) + T[:3, 3]
        axis = rig.projector.R[1 if rows else 0]  # projector x (or y) axis in the left frame
        uv, _ = rig.projector.project(np.vstack([c, c + period_mm * axis]))
        rig = rig.with_period(float(abs(uv[1, 1 if rows else 0] - uv[0, 1 if rows else 0])))
    dent_m = None
    if dent is not None:
        dc, depth, radius = dent
        dent_m = (np.asarray(dc, dtype=np.float64), float(depth), float(radius))
        if not dent_m[2] > 0:
            raise ValueError(f"dent radius must be positive, got {radius}")
    refl = [(np.asarray(c, float), float(r), float(p)) for c, r, p in reflections]
    gen = generator(rng)
    full = 255.0 if bits == 8 else 65535.0
    images, truth = {}, {}
    for name in ("left", "right"):
        dev = getattr(rig, name)
        img, tr = _render_camera(scene, rig, dev, T, rig.pattern.period_px, rows, dent_m, refl, ambient, gain, ss,
                                 float(phase_offset))
        img = img + gen.normal(0.0, noise, img.shape) if noise > 0 else img
        scale = 1.0 if bits == 8 else 257.0
        q = np.clip(np.round(img * scale), 0, full)
        tr["saturated"] = q >= full
        images[name] = q.astype(np.uint8 if bits == 8 else np.uint16)
        truth[name] = tr
    return FringeImages(images["left"], images["right"], rig, T, truth, dent_m)


def demo_scene(width: int = 1000, height: int = 1000, distance: float = 320.0, focal_px: float = 2350.0):
    """The example panel (``cad.examples.wavy_panel``, 120 x 90 mm) and a rig that sees it.

    At the default 1000 x 1000 pixels each camera sees the whole panel at about 0.13 mm per pixel
    (a 1 mm fringe period is 6-8 pixels); smaller images keep the lens and see a central crop.

    Returns
    -------
    model : Model
    rig : Rig
    T_left_model : (4, 4) float64
    """
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.camera.rig import look_at_rig

    model = wavy_panel()
    lo, hi = model.bounds
    rig, T = look_at_rig(0.5 * (lo + hi), distance, width=width, height=height, focal_px=focal_px)
    return model, rig, T
