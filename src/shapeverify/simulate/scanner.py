"""Virtual scanner: a single-shot optical scan of a model, with realistic defects and its truth.

A pinhole camera looks at the model; every pixel's ray is intersected with the model (exact ray
casting on the trimmed NURBS faces of a CAD model via :mod:`shapeverify.camera`; for a mesh or
point-cloud model a z-buffer over densely sampled model points, the ray meeting the tangent plane
of the frontmost sample of its pixel).  Rays that meet the surface at a grazing angle are dropped.
The measured points then get

* depth noise along the ray (Gaussian, ``noise`` mm),
* shadowed regions without data (discs on the surface),
* reflection blobs: discs whose points are pushed off the surface, towards the camera, by
  ``blob_height`` mm (times a smooth profile between 1/2 and 1),
* scattered outliers: a fraction of the points moved along their ray by 0.5..``outlier_range`` mm,
* dents: a smooth bump ``depth * (1 - (s/radius)^2)^2`` along the inward normal,
* a rigid motion from the model frame to the scan frame (a rough fixture).

The result carries the truth for every point (label, the CAD point along its ray and the CAD
normal there) and the true ``T_model_scan``, so registrations and inspections can be judged
against it (:meth:`VirtualScan.accuracy`, the Cramér-Rao check of issue 4).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._random import generator
from ..registration.rigid import (
    apply_transform, fisher_information, invert_transform, make_transform, pose_error, rodrigues,
)
from shapeverify._renamed import grouped_keywords

__all__ = ["ScanEffects", "virtual_scan", "VirtualScan", "Accuracy", "random_motion",
           "INLIER", "OUTLIER", "BLOB", "DENT", "LABELS"]

logger = logging.getLogger(__name__)

INLIER, OUTLIER, BLOB, DENT = 0, 1, 2, 3
LABELS = ("inlier", "outlier", "blob", "dent")


@dataclass(frozen=True)
class Accuracy:
    """Errors of an estimated pose against the truth of a virtual scan.

    crb : float   sqrt(e^T F e), F the Fisher information of the true inliers (chi, 6 dof)
    normal_rms : float   RMS of the normal component of the registration error over the scan (mm)
    rotation_deg : float   rotation error (degrees)
    translation : float   translation error at the scan's centroid (mm)
    e : (6,) rotation vector (rad) and translation (mm) of T_est @ inv(T_true) (model frame)
    """

    crb: float
    normal_rms: float
    rotation_deg: float
    translation: float
    e: np.ndarray = field(repr=False)


@dataclass(frozen=True, eq=False, repr=False)
class VirtualScan:
    """A simulated scan and its truth.

    Attributes
    ----------
    scan : (N, 3) float64
        Measured points in scan coordinates (what a scanner delivers).
    T_model_scan : (4, 4) float64
        The true pose: model = R @ scan + t.
    labels : (N,) int8
        INLIER (0), OUTLIER (1), BLOB (2: reflection), DENT (3: on a simulated dent).
    points : (N, 3) float64
        The CAD point (model frame, without dents) on each point's ray.
    normals : (N, 3) float64
        Outward CAD normal there.
    rays : (N, 3) float64
        Unit ray directions (model frame, camera -> surface).
    face : (N,) int64;  uv : (N, 2) float64
        Face and parameters of each CAD point (uv 0 for mesh and point models).
    camera : PinholeCamera
        The camera, posed in the model frame.
    noise : float
        Depth noise sigma along the rays (mm).
    """

    scan: np.ndarray
    T_model_scan: np.ndarray
    labels: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    rays: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    camera: object
    noise: float

    def __len__(self) -> int:
        return self.scan.shape[0]

    @property
    def inliers(self) -> np.ndarray:
        """(N,) bool: labels == INLIER."""
        return self.labels == INLIER

    def counts(self) -> dict:
        """Number of points per label name."""
        return {name: int(np.sum(self.labels == i)) for i, name in enumerate(LABELS)}

    def fisher(self, sigma: float | None = None) -> np.ndarray:
        """Fisher information (6, 6) of the true inliers at the true pose (sigma: the noise)."""
        s = self.noise if sigma is None else float(sigma)
        m = self.inliers
        return fisher_information(self.points[m], self.normals[m], s)

    def accuracy(self, T_model_scan, sigma: float | None = None) -> Accuracy:
        """Compare an estimated pose with the truth (see :class:`Accuracy`)."""
        T = np.asarray(T_model_scan, np.float64)
        e = pose_error(T, self.T_model_scan)
        crb = float(np.sqrt(max(e @ self.fisher(sigma) @ e, 0.0)))
        true_model = self.points
        scan_true = apply_transform(invert_transform(self.T_model_scan), true_model)
        diff = apply_transform(T, scan_true) - true_model
        normal_rms = float(np.sqrt(np.mean(np.einsum("ij,ij->i", diff, self.normals) ** 2)))
        c = true_model.mean(axis=0)
        dT = T @ invert_transform(self.T_model_scan)
        trans = float(np.linalg.norm(dT[:3, :3] @ c + dT[:3, 3] - c))
        return Accuracy(crb, normal_rms, float(np.degrees(np.linalg.norm(e[:3]))), trans, e)

    def __repr__(self) -> str:
        c = ", ".join(f"{k}={v}" for k, v in self.counts().items())
        return f"VirtualScan(n={len(self)}, {c}, noise={self.noise:g})"


# ------------------------------------------------------------------------------ helpers
def random_motion(angle_deg: float, translation: float, center=(0.0, 0.0, 0.0),
                  rng=None) -> np.ndarray:
    """A rigid motion (4, 4): rotation by exactly ``angle_deg`` about a random axis through
    ``center``, then a translation of length ``translation`` in a random direction.

    ``rng``: None (the fixed seed 0, as everywhere in shapeverify: :mod:`shapeverify._random`),
    an int seed or a Generator; ``np.random.default_rng()`` for fresh randomness."""
    rng = generator(rng)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    tdir = rng.normal(size=3)
    tdir /= np.linalg.norm(tdir)
    R = rodrigues(axis * np.radians(angle_deg))
    c = np.asarray(center, np.float64)
    return make_transform(R, c - R @ c + translation * tdir)


def _model_of(obj):
    m = getattr(obj, "model", None)
    return m if m is not None and hasattr(m, "kind") else obj


def _mean_normal(model) -> np.ndarray:
    """Area-weighted mean outward normal (for the default viewing direction)."""
    if model.kind == "cad":
        acc = np.zeros(3)
        part = model.part_faces() if hasattr(model, "part_faces") else range(len(model.faces))
        for f in (model.faces[i] for i in part):
            (a0, a1), (b0, b1) = f.uv_bounds
            g = np.stack(np.meshgrid(np.linspace(a0, a1, 24), np.linspace(b0, b1, 24)),
                         axis=-1).reshape(-1, 2)
            g = g[f.contains(g)]
            if g.shape[0] == 0:
                continue
            d = f.surface.derivatives(g[:, 0], g[:, 1], 1)
            n = np.cross(d[:, 1, 0], d[:, 0, 1])
            acc += (-1.0 if f.reversed else 1.0) * n.sum(axis=0) * (a1 - a0) * (b1 - b0) / len(g)
    elif model.kind == "mesh":
        v = model.vertices[model.triangles]
        acc = 0.5 * np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]).sum(axis=0)
    else:
        acc = (model.cloud_normals.sum(axis=0) if model.cloud_normals is not None
               else np.zeros(3))
    nrm = np.linalg.norm(acc)
    return acc / nrm if nrm > 1e-9 * max(model.size, 1e-300) ** 2 else np.array([0.0, 0.0, 1.0])


def _auto_camera(model, view, distance, pixel):
    from ..camera.pinhole import PinholeCamera

    b = model.bounds
    center = b.mean(axis=0)
    view = _mean_normal(model) if view is None else np.asarray(view, np.float64)
    view = view / np.linalg.norm(view)
    distance = 2.0 * model.size if distance is None else float(distance)
    eye = center + distance * view
    z = -view
    up = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    Rwc = np.column_stack([x, y, z])
    f = distance / float(pixel)
    corners = np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1)
                        for k in (0, 1)])
    pc = (corners - eye) @ Rwc
    if np.any(pc[:, 2] <= 0):
        raise ValueError("the camera is inside the model's bounding box; increase distance")
    xy = pc[:, :2] / pc[:, 2:3]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    width = int(np.ceil(f * (hi[0] - lo[0]))) + 3
    height = int(np.ceil(f * (hi[1] - lo[1]))) + 3
    return PinholeCamera(f, f, -f * lo[0] + 1.0, -f * lo[1] + 1.0, width, height,
                         make_transform(Rwc, eye))


def _cast_exact(model, cam):
    from ..camera.intersect import intersect_rays

    o, d = cam.pixel_rays()
    h = intersect_rays(model, o, d)
    m = h.hit
    return h.points[m], h.normals[m], d[m], h.face[m].astype(np.int64), h.uv[m]


def _cast_zbuffer(model, cam, pixel):
    """Rays meet the tangent plane of a model sample of the frontmost surface in their pixel.

    Samples ``pixel / 3`` apart are projected; per pixel, the front layer is the front-facing
    samples within a few pixel footprints of the smallest depth (the z-buffer), and of those the
    sample closest to the pixel's ray carries the tangent plane the ray is intersected with.
    A ray farther than 0.75 sample spacings from every front sample misses the surface (the
    silhouette) and gives no point.
    """
    spacing = pixel / 3.0
    mp = model.sample(spacing)
    pix, depth = cam.project(mp.points)
    ij = np.rint(pix).astype(np.int64)
    ok = ((depth > 0) & (ij[:, 0] >= 0) & (ij[:, 0] < cam.width) & (ij[:, 1] >= 0)
          & (ij[:, 1] < cam.height))
    idx = np.flatnonzero(ok)
    key = ij[idx, 1] * cam.width + ij[idx, 0]
    order = np.lexsort((depth[idx], key))
    idx, key = idx[order], key[order]
    start = np.ones(idx.size, bool)
    start[1:] = key[1:] != key[:-1]
    group = np.cumsum(start) - 1
    zfront = depth[idx][start][group]
    # lateral distance of each sample from its pixel's centre ray (mm at the sample's depth)
    lateral = np.hypot((pix[idx, 0] - ij[idx, 0]) / cam.fx,
                       (pix[idx, 1] - ij[idx, 1]) / cam.fy) * depth[idx]
    view = mp.points[idx] - cam.center
    front = np.einsum("ij,ij->i", mp.normals[idx], view) < 0
    layer = front & (depth[idx] <= zfront * (1.0 + 6.0 / cam.fx))  # 6 pixel footprints
    lat = np.where(layer, lateral, np.inf)
    o2 = np.lexsort((lat, group))
    first = np.ones(o2.size, bool)
    first[1:] = group[o2][1:] != group[o2][:-1]
    pick = o2[first]
    pick = pick[lat[pick] <= 0.75 * spacing]
    s = idx[pick]
    pixels = np.column_stack([ij[s, 0], ij[s, 1]]).astype(np.float64)
    o, d = cam.rays(pixels)
    n = mp.normals[s]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.einsum("ij,ij->i", n, mp.points[s] - o) / np.einsum("ij,ij->i", n, d)
    good = np.isfinite(lam) & (lam > 0)
    p = o + lam[:, None] * d
    return (p[good], n[good], d[good], mp.face[s][good].astype(np.int64), mp.uv[s][good])


def _pick_centers(points, radii, rng, taken):
    """Random disc centres on the scanned surface, well inside it, not overlapping.

    Candidates lie in the middle of the scan along its two main axes (principal axes): at most
    60 % of the half extent from the centroid, less the disc radius, so the disc stays on the
    part (for a disc larger than that allows, within 30 % of the half extent).
    """
    c0 = points.mean(axis=0)
    _, V = np.linalg.eigh(np.cov((points - c0).T))
    uv = (points - c0) @ V[:, [2, 1]]
    half = np.abs(uv).max(axis=0)
    out = []
    for r in radii:
        lim = np.maximum(0.6 * half - r, 0.3 * half)
        cand = np.flatnonzero(np.all(np.abs(uv) <= lim, axis=1))
        for _ in range(200):
            c = points[cand[rng.integers(cand.size)]]
            if all(np.linalg.norm(c - c1) > r + r1 for c1, r1 in taken):
                break
        taken.append((c, r))
        out.append(c)
    return out


def _nonneg(x, name):
    x = float(x)
    if not (np.isfinite(x) and x >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {x}")
    return x


# ------------------------------------------------------------------------------ the scanner
@dataclass(frozen=True)
class ScanEffects:
    """What the sensor and the scene add to the ideal points of :func:`virtual_scan` (its
    ``effects=``; the loose keywords of these names still work, with a DeprecationWarning); the
    fields are described in its Parameters."""

    max_incidence: float = 75.0
    shadows: int = 0
    shadow_radius: float | None = None
    blobs: int = 0
    blob_radius: float | None = None
    blob_height: float = 2.0
    outlier_fraction: float = 0.0
    outlier_range: float = 5.0
    dents: tuple = ()


@grouped_keywords("effects", ScanEffects)
def virtual_scan(model, *, camera=None, view=None, distance=None, pixel: float = 1.0,
                 noise: float = 0.02, motion=None, zbuffer: bool | None = None, rng=None,
                 effects: ScanEffects = ScanEffects()) -> VirtualScan:
    """Simulate one optical scan of a model (see the module docstring for the physics).

    Parameters
    ----------
    model : Model or Prepared
        The part (a Prepared model's ``.model`` is used).
    camera : PinholeCamera or None
        Camera posed in the model frame; None places one at ``distance`` along ``view`` from
        the model's centre, with pixels ``pixel`` mm wide at that distance, framing the model.
    view : (3,) or None
        Direction from the part to the camera (None: the model's mean outward normal).
    distance : float or None
        Camera distance from the model centre (mm; default twice the model's size).
    pixel : float
        Pixel footprint at the model centre (mm): about ``area / pixel^2`` points.
    noise : float
        Depth noise sigma along the rays (mm).
    effects : ScanEffects
        Groups ``max_incidence``, ``shadows``, ``shadow_radius``, ``blobs``,
        ``blob_radius``, ``blob_height``, ``outlier_fraction``, ``outlier_range``,
        ``dents`` (described below); the loose keywords still work, with a
        DeprecationWarning.
    max_incidence : float
        Rays meeting the surface at more than this angle from the normal (deg) are dropped.
    shadows, blobs : int
        Numbers of shadowed discs (no data) and reflection blobs.
    shadow_radius, blob_radius : float or None
        Disc radii (mm; default 8 % and 5 % of the model size).
    blob_height : float
        How far a blob is pushed off the surface towards the camera (mm).
    outlier_fraction : float in [0, 1)
        Fraction of the scan's points made scattered outliers.
    outlier_range : float
        Outliers move 0.5..outlier_range mm along their ray, either way.
    dents : sequence of (depth, radius)
        Smooth dents (depth > 0 into the material, < 0 a bump), mm.
    motion : None, (angle_deg, translation_mm) or (4, 4)
        Rigid motion model -> scan: None is the identity; a pair draws a random axis and
        direction (rotation about the centroid of the scanned points); a matrix is used as
        given (it is ``inv(T_model_scan)``).
    zbuffer : bool or None
        Force the z-buffer (True) or exact ray casting (False; CAD models only);
        None: exact for CAD models, z-buffer otherwise.
    rng : None, int or Generator
        The noise, the motion and the shadows' places.  None means the fixed seed 0 (as
        everywhere in shapeverify, :mod:`shapeverify._random`: the same call gives the same
        scan; before issue 31 it meant fresh randomness here); pass
        ``np.random.default_rng()`` for a different scan on each call.

    Returns
    -------
    VirtualScan

    Raises
    ------
    ValueError
        On negative sizes, a bad motion, or when no ray meets the model.
    """
    max_incidence = effects.max_incidence
    shadows = effects.shadows
    shadow_radius = effects.shadow_radius
    blobs = effects.blobs
    blob_radius = effects.blob_radius
    blob_height = effects.blob_height
    outlier_fraction = effects.outlier_fraction
    outlier_range = effects.outlier_range
    dents = effects.dents
    rng = generator(rng)
    model = _model_of(model)
    noise = _nonneg(noise, "noise")
    pixel = float(pixel)
    if not (np.isfinite(pixel) and pixel > 0):
        raise ValueError(f"pixel must be a positive footprint in mm, got {pixel}")
    of = float(outlier_fraction)
    if not 0 <= of < 1:
        raise ValueError(f"outlier_fraction must lie in [0, 1), got {of}")
    size = model.size
    shadow_radius = (0.08 * size if shadow_radius is None
                     else _nonneg(shadow_radius, "shadow_radius"))
    blob_radius = 0.05 * size if blob_radius is None else _nonneg(blob_radius, "blob_radius")
    dents = [(float(a), _nonneg(b, "dent radius")) for a, b in dents]

    cam = _auto_camera(model, view, distance, pixel) if camera is None else camera
    use_z = (model.kind != "cad") if zbuffer is None else bool(zbuffer)
    if not use_z and model.kind != "cad":
        raise ValueError("exact ray casting needs a CAD model; use zbuffer=True")
    P, Nrm, D, face, uv = _cast_zbuffer(model, cam, pixel) if use_z else _cast_exact(model, cam)
    cosang = -np.einsum("ij,ij->i", Nrm, D)
    keep = cosang >= np.cos(np.radians(max_incidence))
    P, Nrm, D, face, uv, cosang = P[keep], Nrm[keep], D[keep], face[keep], uv[keep], cosang[keep]
    if P.shape[0] == 0:
        raise ValueError("no camera ray meets the model's front at less than max_incidence; "
                         "check the camera pose")
    if P.shape[0] < 10 and (shadows or blobs or dents):
        raise ValueError(f"only {P.shape[0]} camera rays meet the model: pixel={pixel:g} mm is too "
                         f"coarse to place shadows, blobs or dents on a part of size {size:.3g} mm; "
                         f"give a smaller pixel (e.g. pixel={size / 100:.2g})")

    taken = []
    keep = np.ones(P.shape[0], bool)
    for c in _pick_centers(P, [shadow_radius] * int(shadows), rng, taken):
        keep &= np.linalg.norm(P - c, axis=1) > shadow_radius
    P, Nrm, D, face, uv, cosang = P[keep], Nrm[keep], D[keep], face[keep], uv[keep], cosang[keep]
    n = P.shape[0]
    labels = np.zeros(n, np.int8)
    lam = np.zeros(n)  # offset along the ray from the CAD point
    for (depth, radius), c in zip(dents, _pick_centers(P, [r for _, r in dents], rng, taken)):
        s = np.linalg.norm(P - c, axis=1) / max(radius, 1e-300)
        m = s < 1.0
        h = depth * (1.0 - s[m] ** 2) ** 2
        lam[m] += h / cosang[m]
        labels[m] = DENT
    for c in _pick_centers(P, [blob_radius] * int(blobs), rng, taken):
        s = np.linalg.norm(P - c, axis=1) / max(blob_radius, 1e-300)
        m = s < 1.0
        lam[m] -= blob_height * (1.0 - 0.5 * s[m] ** 2)
        labels[m] = BLOB
    n_out = int(round(of * n))
    free = np.flatnonzero(labels == INLIER)
    if n_out > free.size:
        raise ValueError(f"outlier_fraction={of} asks for {n_out} outliers but only "
                         f"{free.size} points are not already blobs or dents")
    if n_out:
        o = rng.choice(free, n_out, replace=False)
        lo = min(0.5, outlier_range)
        lam[o] += rng.choice([-1.0, 1.0], n_out) * rng.uniform(lo, outlier_range, n_out)
        labels[o] = OUTLIER
    lam += rng.normal(0.0, noise, n) if noise > 0 else 0.0
    measured = P + lam[:, None] * D

    if motion is None:
        M = np.eye(4)
    else:
        mo = np.asarray(motion, np.float64)
        if mo.shape == (2,):
            M = random_motion(mo[0], mo[1], center=P.mean(axis=0), rng=rng)
        elif mo.shape == (4, 4):
            M = mo
        else:
            raise ValueError("motion must be None, (angle_deg, translation_mm) or a (4, 4) "
                             f"matrix, got shape {mo.shape}")
    scan = apply_transform(M, measured)
    logger.debug("virtual scan: %d points (%s)", n, np.bincount(labels, minlength=4))
    return VirtualScan(scan=scan, T_model_scan=invert_transform(M), labels=labels, points=P,
                       normals=Nrm, rays=D, face=face, uv=uv, camera=cam, noise=noise)
