"""Off-axis digital holograms of a surface, with speckle, for dual-wavelength holography (Paper V).

Physics (collimated illumination along the viewing direction, reflection; Schnars & Jüptner 2005):

1. object wave at the object plane: ``U = a * exp(i 4 pi (z + h) / lambda)`` where ``z`` is the
   depth (mm, from a CAD depth render -- :func:`shapeverify.camera.render` -- or any depth map),
   ``h`` the height of the surface roughness at the pixel (random, seeded; the same ``h`` for
   both wavelengths, so the speckle is common to the two holograms as on a real part) and ``a``
   the reflectance (0 where there is no surface);
2. the imaging aperture keeps spatial frequencies up to ``aperture`` cycles/pixel (this sets
   the speckle size, about ``1 / (2 * aperture)`` pixels);
3. optionally the wave travels a further ``distance`` mm to the camera (angular spectrum);
4. a plane reference wave ``R = r * exp(-2 pi i (c . x))`` at an angle gives the carrier ``c``
   (cycles/pixel): ``c = pitch * sin(angle) / lambda`` per axis, so it differs slightly between
   the two wavelengths;
5. the camera records ``|U + R|^2`` plus Gaussian noise, optionally quantised to ``bits`` with
   saturation.

The result keeps the true object wave and carrier so that reconstructions can be checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._random import generator
from scipy import fft as sfft
from shapeverify._renamed import grouped_keywords

__all__ = ["OffAxis", "Hologram", "simulate_hologram", "dual_wavelength_holograms", "rough_surface",
           "grooved_plate", "depth_from_model"]


@dataclass(frozen=True, repr=False)
class Hologram:
    """A simulated hologram and its truth.

    Attributes
    ----------
    intensity : (H, W) float64
        Recorded image (grey values; integers when quantised).
    field : (H, W) complex128
        True object wave at the camera (what :func:`shapeverify.phase.reconstruct` recovers,
        before back-propagation).
    object_field : (H, W) complex128
        Band-limited object wave in the object's image plane.
    carrier : (cx, cy)
        Carrier of the +1 order (cycles/pixel).
    wavelength : float
        mm.
    """

    intensity: np.ndarray
    field: np.ndarray
    object_field: np.ndarray
    carrier: tuple
    wavelength: float

    def __repr__(self):
        return (f"Hologram(shape={self.intensity.shape}, wavelength={self.wavelength * 1e6:.2f} nm, "
                f"carrier=({self.carrier[0]:.4f}, {self.carrier[1]:.4f}))")


def rough_surface(shape, rms: float = 1e-3, rng=0):
    """Roughness heights (mm) per pixel: independent Gaussian, standard deviation `rms`.

    With ``rms`` well above ``lambda / (4 pi)`` (50 nm for red light) the speckle is fully
    developed; with ``rms`` well below ``Lambda / (4 pi)`` the two wavelengths' speckle is the
    same and cancels in the phase difference.
    """
    if not (np.isfinite(rms) and rms >= 0):
        raise ValueError(f"rms must be finite and >= 0 (mm), got {rms!r}")
    return float(rms) * generator(rng).standard_normal(tuple(shape))


def _lowpass(u, aperture):
    F = sfft.fft2(u)
    fy = sfft.fftfreq(u.shape[0])[:, None]
    fx = sfft.fftfreq(u.shape[1])[None, :]
    F[np.hypot(fx, fy) > aperture] = 0.0
    return sfft.ifft2(F)


@dataclass(frozen=True)
class OffAxis:
    """The off-axis reference of :func:`simulate_hologram` (its ``off_axis=``; the loose
    keywords of these names still work, with a DeprecationWarning)."""

    carrier: tuple = (0.25, 0.25)
    aperture: float = 0.1
    reference_ratio: float = 1.0


@grouped_keywords("off_axis", OffAxis)
def simulate_hologram(depth, wavelength: float, *, heights=None, reflectance=None,
                      distance: float = 0.0, pixel_pitch: float | None = None, noise: float = 0.0,
                      bits: int | None = None, rng=0, off_axis: OffAxis = OffAxis()) -> Hologram:
    """Off-axis hologram of a surface given as a depth map.

    Parameters
    ----------
    depth : (H, W) array_like of float
        Depth along the viewing direction (mm), NaN where there is no surface (e.g.
        ``camera.render(prep, cam)["depth"]``).
    wavelength : float
        mm (e.g. 632.8e-6).
    heights : (H, W) array_like or None
        Roughness heights (mm), e.g. :func:`rough_surface`; ``None``: a smooth (mirror) surface.
    reflectance : (H, W) array_like or None
        Amplitude reflectance >= 0 (``None``: 1 on the surface).
    off_axis : OffAxis
        Groups ``carrier``, ``aperture``, ``reference_ratio`` (described below); the loose
        keywords still work, with a DeprecationWarning.
    carrier : (cx, cy)
        Carrier of the +1 order (cycles/pixel).  Needs ``|c| >= 3 * aperture`` and
        ``|cx|, |cy| + aperture < 0.5`` for the orders not to overlap.
    aperture : float
        Radius of the imaging pupil (cycles/pixel).
    reference_ratio : float > 0
        Reference intensity over the mean object intensity.
    distance : float
        Propagation (mm) from the image plane to the camera (needs `pixel_pitch`).
    pixel_pitch : float or None
        mm.
    noise : float >= 0
        Camera noise, standard deviation relative to the mean intensity.
    bits : int or None
        Quantise to this many bits (full scale at the 99.9th percentile; brighter pixels
        saturate).
    rng : int or Generator
        Seed of the camera noise.

    Returns
    -------
    Hologram

    Raises
    ------
    ValueError
        Bad shapes, a non-finite depth everywhere, overlapping orders, bad parameters.
    """
    carrier = off_axis.carrier
    aperture = off_axis.aperture
    reference_ratio = off_axis.reference_ratio
    z = np.asarray(depth, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 8:
        raise ValueError(f"depth must be a 2-D map of at least 8 x 8 pixels, got shape {z.shape}")
    surf = np.isfinite(z)
    if not surf.any():
        raise ValueError("depth is NaN everywhere: there is no surface to record")
    lam = float(wavelength)
    if not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"wavelength must be > 0 (mm), got {wavelength!r}")
    cx, cy = (float(v) for v in carrier)
    if not 0 < aperture < 0.25:
        raise ValueError(f"aperture must be in (0, 0.25) cycles/pixel, got {aperture!r}")
    if np.hypot(cx, cy) < 3 * aperture or max(abs(cx), abs(cy)) + aperture >= 0.5:
        raise ValueError(f"carrier {carrier!r} and aperture {aperture!r} overlap the orders: need "
                         "|c| >= 3 * aperture and |cx|, |cy| + aperture < 0.5")
    if not reference_ratio > 0:
        raise ValueError(f"reference_ratio must be > 0, got {reference_ratio!r}")
    if noise < 0:
        raise ValueError(f"noise must be >= 0, got {noise!r}")
    h = np.zeros(z.shape) if heights is None else np.asarray(heights, dtype=np.float64)
    a = surf.astype(np.float64) if reflectance is None else np.asarray(reflectance, np.float64) * surf
    if h.shape != z.shape or a.shape != z.shape:
        raise ValueError("heights and reflectance must have the depth map's shape")
    u0 = a * np.exp(1j * (4 * np.pi / lam) * np.where(surf, z + h, 0.0))
    obj = _lowpass(u0, aperture)
    obj /= np.sqrt(np.mean(np.abs(obj[surf]) ** 2))
    cam = obj
    if distance:
        from shapeverify.phase.hologram import angular_spectrum

        if pixel_pitch is None:
            raise ValueError("distance != 0 needs pixel_pitch (mm)")
        cam = angular_spectrum(obj, float(distance), lam, float(pixel_pitch))
    H, W = z.shape
    y, x = np.mgrid[0:H, 0:W]
    R = np.sqrt(reference_ratio) * np.exp(-2j * np.pi * (cx * x + cy * y))
    inten = np.abs(cam + R) ** 2
    g = generator(rng)
    if noise > 0:
        inten = inten + noise * inten.mean() * g.standard_normal(inten.shape)
    if bits is not None:
        full = float(np.quantile(inten, 0.999))
        top = 2 ** int(bits) - 1
        inten = np.clip(np.rint(inten / full * top), 0, top)
    return Hologram(intensity=inten, field=cam, object_field=obj, carrier=(cx, cy), wavelength=lam)


def dual_wavelength_holograms(depth, lambda1: float, lambda2: float, *, roughness: float = 1e-3,
                              pixel_pitch: float = 0.01, reference_angle=(None, None),
                              carrier=(0.25, 0.25), rng=0, **kwargs):
    """Two holograms of the same rough surface at two wavelengths (common speckle).

    The reference wave has a fixed angle; its carrier at ``lambda1`` is `carrier` (cycles/pixel)
    unless `reference_angle` (radians per axis) is given, and at ``lambda2`` it is scaled by
    ``lambda1 / lambda2`` (``c = pitch * sin(angle) / lambda``).

    Parameters
    ----------
    depth : (H, W) array_like
        Depth map (mm), NaN off the surface.
    lambda1, lambda2 : float
        Wavelengths (mm).
    roughness : float
        RMS roughness height (mm) of :func:`rough_surface`.
    pixel_pitch : float
        mm (used for the reference angle and for `distance`).
    rng : int
        Seed: roughness from ``rng``, camera noise from ``rng + 1`` and ``rng + 2``.
    **kwargs
        Passed to :func:`simulate_hologram` (aperture, noise, bits, distance, ...).

    Returns
    -------
    (Hologram, Hologram)
    """
    z = np.asarray(depth, dtype=np.float64)
    h = rough_surface(z.shape, roughness, rng)
    if reference_angle[0] is not None:
        c1 = tuple(pixel_pitch * np.sin(t) / lambda1 for t in reference_angle)
    else:
        c1 = tuple(float(v) for v in carrier)
    c2 = tuple(v * lambda1 / lambda2 for v in c1)
    seed = int(rng) if isinstance(rng, (int, np.integer)) else 0
    off_axis = {k: kwargs.pop(k) for k in ("aperture", "reference_ratio") if k in kwargs}
    h1 = simulate_hologram(z, lambda1, heights=h, pixel_pitch=pixel_pitch, rng=seed + 1,
                           off_axis=OffAxis(carrier=c1, **off_axis), **kwargs)
    h2 = simulate_hologram(z, lambda2, heights=h, pixel_pitch=pixel_pitch, rng=seed + 2,
                           off_axis=OffAxis(carrier=c2, **off_axis), **kwargs)
    return h1, h2


def grooved_plate(shape=(256, 256), pixel_pitch: float = 0.05, groove_width: float = 3.0,
                  groove_depth: float = 1.0, standoff: float = 0.0, tilt=(0.0, 0.0)):
    """Depth map (mm) of a flat plate with a straight milled groove across it (Paper V's part).

    Parameters
    ----------
    shape : (H, W)
        Pixels.
    pixel_pitch : float
        mm per pixel on the part.
    groove_width, groove_depth : float
        mm; the groove runs along the rows (vertical in the image), centred.
    standoff : float
        Depth of the plate's top face (mm).
    tilt : (tx, ty)
        Plate slope (mm per mm) along x and y.

    Returns
    -------
    depth : (H, W) float64 (larger = further from the camera)
    groove : (H, W) bool, True on the groove floor
    """
    H, W = (int(v) for v in shape)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    xm = (x - (W - 1) / 2) * pixel_pitch
    ym = (y - (H - 1) / 2) * pixel_pitch
    groove = np.abs(xm) < groove_width / 2
    depth = standoff + tilt[0] * xm + tilt[1] * ym + np.where(groove, groove_depth, 0.0)
    return depth, groove



def depth_from_model(prep, camera, T_world_model=None, kind: str = "range"):
    """One-way optical path per pixel (mm; NaN where the model is not seen) of a CAD model.

    Exact ray-CAD intersection of every pixel (:func:`shapeverify.camera.make_view`).

    Parameters
    ----------
    prep : Prepared
    camera : shapeverify.camera.PinholeCamera
    T_world_model : (4, 4) or None
        Pose of the model in the camera's world (measurement) frame.
    kind : {"range", "z"}
        ``"range"``: distance from the camera centre along each pixel's ray -- the one-way path
        of the divergent illumination from a source at the camera centre, the geometry of
        :class:`shapeverify.phase.HolographySetup` with ``source=None`` (so that the holograms'
        phase difference is what :func:`shapeverify.phase.unwrap_with_cad` predicts);
        ``"z"``: depth along the optical axis (collimated illumination).

    Returns
    -------
    (H, W) float64
    """
    from shapeverify.camera import make_view

    if kind not in ("range", "z"):
        raise ValueError(f"kind must be 'range' or 'z', got {kind!r}")
    T = np.eye(4) if T_world_model is None else np.asarray(T_world_model, dtype=np.float64)
    hits = make_view(prep, camera, T).hits
    pts = np.where(hits.hit[:, None], hits.points, 0.0) @ T[:3, :3].T + T[:3, 3]
    if kind == "range":
        d = np.linalg.norm(pts - np.asarray(camera.center, dtype=np.float64), axis=1)
    else:
        d = camera.to_camera(pts)[:, 2]
    return np.where(hits.hit, d, np.nan).reshape(camera.height, camera.width)
