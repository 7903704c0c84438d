"""Off-axis digital holograms: carrier filtering, angular-spectrum propagation, two wavelengths.

Recording model (Schnars & Jüptner 2005, Ch. 3): the camera records the intensity
``I = |O + R|^2 = |O|^2 + |R|^2 + O R* + O* R`` of the object wave ``O`` and a plane reference
wave ``R = exp(-2*pi*i (c . x))`` arriving at an angle.  In the Fourier domain the term ``O R*``
is the object's spectrum shifted to the *carrier* ``c`` (cycles/pixel); the zero order
(``|O|^2 + |R|^2``) sits at the centre and the twin image ``O* R`` at ``-c``.  When the object's
band (radius ``NA`` in cycles/pixel, set by the imaging aperture) satisfies ``|c| >= 3 NA`` the
three do not overlap, and ``O`` is recovered exactly by demodulation and a low-pass filter:
``O ~ lowpass(I * exp(-2*pi*i (c . x)))`` (:func:`reconstruct`).  If the camera is not in the
object's image plane, the field is then propagated to it by the angular spectrum method
(:func:`angular_spectrum`).  Two holograms at ``lambda1``, ``lambda2`` give the phase at the
synthetic wavelength, ``angle(O1 conj(O2))`` (:func:`shapeverify.phase.phase_difference`); it is
unwrapped with the CAD prediction (:func:`shapeverify.phase.unwrap_with_reference`) and turned
into depth (:func:`shapeverify.phase.phase_to_depth`) -- :func:`dual_wavelength_depth`.

Conventions: the first image axis is ``y`` (rows), the second ``x`` (columns); a carrier is
``(cx, cy)`` in cycles per pixel, ``|cx|, |cy| < 0.5``.  The object wave's phase grows with the
optical path (``+2*pi*L/lambda``), as in :mod:`shapeverify.phase.holography`.  Lengths in mm.

References
----------
U. Schnars, W. Jüptner, *Digital Holography*, Springer 2005, Ch. 3 and 5; E. Cuche, P. Marquet,
C. Depeursinge, Appl. Opt. 39 (2000) 4070 (spatial filtering of off-axis holograms); J. W.
Goodman, *Introduction to Fourier Optics*, 3rd ed. 2005, Ch. 3.10 (angular spectrum);
Bergström (2011), Paper V.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

from .holography import phase_difference, phase_to_depth, synthetic_wavelength
from shapeverify._renamed import grouped_keywords

__all__ = ["Reconstruction", "find_carrier", "reconstruct", "angular_spectrum", "synthetic_phase",
           "dual_wavelength_depth", "HologramDepth", "hologram_file"]


def _check_image(h, name="hologram"):
    a = np.asarray(h)
    if a.ndim != 2 or a.shape[0] < 8 or a.shape[1] < 8:
        raise ValueError(f"{name} must be a 2-D intensity image of at least 8 x 8 pixels, got shape {a.shape}")
    if a.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be a real intensity image, got dtype {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} holds NaN/inf values; an intensity image must be finite")
    return a


def _freq_grid(shape):
    fy = sfft.fftfreq(shape[0])[:, None]
    fx = sfft.fftfreq(shape[1])[None, :]
    return fx, fy


def find_carrier(hologram, dc_radius: float = 0.06):
    """Carrier ``(cx, cy)`` (cycles/pixel) of the +1 order of an off-axis hologram.

    The +1 order is taken as the side lobe in the half-plane ``cx > 0`` (or ``cx == 0, cy > 0``);
    starting from the brightest (smoothed) frequency there, beyond ``2 * dc_radius`` of the zero
    order, its position is refined by mean shift (the energy centroid of ``|FFT|^2`` within
    ``|c| / 3`` of the estimate, repeated), which converges to the centre of a speckle lobe that
    fills the aperture.  If the reconstructed depth comes out inverted, the
    set-up has its +1 order in the other half-plane: pass ``carrier=-c`` to :func:`reconstruct`.

    Parameters
    ----------
    hologram : (H, W) array_like of float
    dc_radius : float
        Radius (cycles/pixel) around the zero order that is excluded, and of the centroid window.

    Returns
    -------
    (cx, cy) : tuple of float

    Raises
    ------
    ValueError
        Not a finite 2-D image, or no side lobe outside the zero order.
    """
    a = _check_image(hologram)
    F = sfft.fft2(a - a.mean())
    P = np.abs(F) ** 2
    fx, fy = _freq_grid(a.shape)
    r = np.hypot(fx, fy)
    half = (fx > 0) | ((fx == 0) & (fy > 0))
    cand = np.where(half & (r > 2 * dc_radius), P, 0.0)
    if not cand.any():
        raise ValueError("no side lobe found: the image has no off-axis carrier outside the zero order")
    # smooth over a few bins so that one bright speckle does not decide the lobe
    from scipy import ndimage
    sm = ndimage.uniform_filter(cand, size=5, mode="wrap")
    k = np.unravel_index(int(np.argmax(sm)), P.shape)
    c = np.array([fx[0, k[1]], fy[k[0], 0]])
    # mean shift: the centroid of the power within |c| / 3 of the estimate, repeated; converges
    # to the centre of the lobe (the pupil disc filled with speckle), not to its brightest bin
    for _ in range(20):
        rad = max(np.hypot(*c) / 3.0, dc_radius)
        w = P * ((np.hypot(fx - c[0], fy - c[1]) <= rad) & half)
        if w.sum() <= 0:
            break
        c_new = np.array([(w * fx).sum() / w.sum(), (w * fy).sum() / w.sum()])
        if np.hypot(*(c_new - c)) < 1e-7:
            c = c_new
            break
        c = c_new
    cx, cy = float(c[0]), float(c[1])
    return cx, cy


def reconstruct(hologram, carrier=None, radius: float | None = None, distance: float = 0.0,
                wavelength: float | None = None, pixel_pitch: float | None = None):
    """Complex object field from an off-axis hologram (carrier filtering + optional propagation).

    Parameters
    ----------
    hologram : (H, W) array_like of float
        Recorded intensity.
    carrier : (cx, cy) or None
        Position of the +1 order in cycles/pixel (``None``: :func:`find_carrier`).  The exact
        value from the set-up's calibration (``sin(angle) * pitch / wavelength``) avoids a
        residual phase tilt.
    radius : float or None
        Radius (cycles/pixel) of the circular low-pass around the demodulated order (``None``:
        ``|carrier| / 3``, the largest that cannot reach the zero order of an object band that
        does not overlap it).
    distance : float
        Distance (mm) the wave travelled from the object's image plane to the camera (0: the
        camera is in focus); the reconstructed field is propagated back by ``-distance``.
    wavelength, pixel_pitch : float or None
        In mm; needed only when ``distance != 0``.

    Returns
    -------
    field : (H, W) complex128
        Object wave ``O`` (up to the constant reference amplitude).

    Raises
    ------
    ValueError
        Bad image; carrier outside ``(-0.5, 0.5)`` or zero; radius not in ``(0, 0.5)``;
        ``distance != 0`` without wavelength and pitch.
    """
    a = _check_image(hologram)
    c = find_carrier(a) if carrier is None else tuple(float(v) for v in carrier)
    if len(c) != 2 or not all(np.isfinite(c)) or max(abs(c[0]), abs(c[1])) >= 0.5 or np.hypot(*c) == 0:
        raise ValueError(f"carrier must be (cx, cy) in cycles/pixel with |cx|, |cy| < 0.5 and not 0, got {carrier!r}")
    rad = np.hypot(*c) / 3.0 if radius is None else float(radius)
    if not 0 < rad < 0.5:
        raise ValueError(f"radius must be in (0, 0.5) cycles/pixel, got {radius!r}")
    H, W = a.shape
    y, x = np.mgrid[0:H, 0:W]
    demod = (a - a.mean()) * np.exp(-2j * np.pi * (c[0] * x + c[1] * y))
    F = sfft.fft2(demod)
    fx, fy = _freq_grid(a.shape)
    F[np.hypot(fx, fy) > rad] = 0.0
    field = sfft.ifft2(F)
    if distance:
        if wavelength is None or pixel_pitch is None:
            raise ValueError("distance != 0 needs wavelength and pixel_pitch (mm) for the propagation")
        field = angular_spectrum(field, -float(distance), wavelength, pixel_pitch)
    return field


def angular_spectrum(field, distance: float, wavelength: float, pixel_pitch: float):
    """Propagate a complex field by `distance` with the angular spectrum method (exact scalar).

    ``U(z + d) = IFFT(FFT(U) * exp(2*pi*i d sqrt(1/lambda^2 - fx^2 - fy^2)))``; evanescent
    components (``fx^2 + fy^2 > 1/lambda^2``) are dropped.  Periodic boundaries (pad the field
    if it has energy near the border).

    Parameters
    ----------
    field : (H, W) complex array_like
    distance, wavelength, pixel_pitch : float
        mm (distance may be negative: back-propagation).

    Returns
    -------
    (H, W) complex128

    Raises
    ------
    ValueError
        Not 2-D, non-finite, or non-positive wavelength/pitch.
    """
    u = np.asarray(field, dtype=np.complex128)
    if u.ndim != 2 or not np.all(np.isfinite(u)):
        raise ValueError(f"field must be a finite 2-D complex array, got shape {u.shape}")
    lam, dx, d = float(wavelength), float(pixel_pitch), float(distance)
    if not (lam > 0 and dx > 0 and np.isfinite(d)):
        raise ValueError(f"wavelength and pixel_pitch must be > 0 and distance finite, got "
                         f"{wavelength!r}, {pixel_pitch!r}, {distance!r}")
    fx, fy = _freq_grid(u.shape)
    kx, ky = fx / dx, fy / dx                       # cycles/mm
    arg = 1.0 / lam ** 2 - kx ** 2 - ky ** 2
    Hf = np.where(arg > 0, np.exp(2j * np.pi * d * np.sqrt(np.maximum(arg, 0.0))), 0.0)
    return sfft.ifft2(sfft.fft2(u) * Hf)


@dataclass(frozen=True, repr=False)
class HologramDepth:
    """Result of :func:`dual_wavelength_depth`.

    Attributes
    ----------
    depth : (H, W) float64
        Depth (mm) along the viewing direction, NaN where not measured.
    psi : (H, W) float64
        Wrapped phase at the synthetic wavelength.
    phase : (H, W) float64
        Unwrapped phase (with the reference).
    quality : (H, W) float64
        Speckle quality in [0, 1]: ``|mean(O1 conj(O2))| / mean(|O1| |O2|)`` over the filter
        window (low in dark speckles and where the two wavelengths decorrelate).
    synthetic : float
        Synthetic wavelength (mm).
    """

    depth: np.ndarray
    psi: np.ndarray
    phase: np.ndarray
    quality: np.ndarray
    synthetic: float

    def __repr__(self):
        ok = np.isfinite(self.depth)
        return (f"HologramDepth(shape={self.depth.shape}, synthetic={self.synthetic:.4g} mm, "
                f"measured={ok.mean():.1%})")


@dataclass(frozen=True)
class Reconstruction:
    """How the holograms are reconstructed (the ``reconstruction=`` of :func:`synthetic_phase`
    and :func:`dual_wavelength_depth`; the loose keywords of these names still work, with a
    DeprecationWarning); the fields are described in :func:`dual_wavelength_depth`'s
    Parameters."""

    carrier1: tuple | None = None
    carrier2: tuple | None = None
    radius: float | None = None
    distance: float = 0.0
    pixel_pitch: float | None = None
    window: int = 5
    same_reference_angle: bool = True


@grouped_keywords("reconstruction", Reconstruction)
def synthetic_phase(h1, h2, lambda1: float, lambda2: float,
                    reconstruction: Reconstruction = Reconstruction()):
    """Wrapped phase at the synthetic wavelength from two off-axis holograms, and its quality.

    The input of :func:`shapeverify.phase.unwrap_with_cad` (the predict-unwrap-register loop of
    Paper V) or :func:`shapeverify.phase.unwrap_with_reference`.  Parameters as
    :func:`dual_wavelength_depth`.

    Returns
    -------
    psi : (H, W) float64
        ``angle(mean(O1 conj(O2)))`` over the `window` box, in ``(-pi, pi]`` (NaN where a field
        is 0); it equals ``2*pi*L / Lambda`` modulo ``2*pi`` for the optical path ``L``.
    quality : (H, W) float64 in [0, 1]
        ``|mean(O1 conj(O2))| / mean(|O1| |O2|)`` over the box (low in dark speckles and where
        the two wavelengths' speckle decorrelates, e.g. on steep slopes).
    """
    carrier1 = reconstruction.carrier1
    carrier2 = reconstruction.carrier2
    radius = reconstruction.radius
    distance = reconstruction.distance
    pixel_pitch = reconstruction.pixel_pitch
    window = reconstruction.window
    same_reference_angle = reconstruction.same_reference_angle
    from scipy import ndimage

    a1 = _check_image(h1, "h1")
    a2 = _check_image(h2, "h2")
    if a1.shape != a2.shape:
        raise ValueError(f"h1 and h2 must have the same shape, got {a1.shape} and {a2.shape}")
    c1 = find_carrier(a1) if carrier1 is None else carrier1
    if carrier2 is None:
        # one reference arm: the same angle at both wavelengths, c = pitch sin(angle) / lambda;
        # an error in c1 then cancels in O1 conj(O2) up to a factor 1 - lambda1 / lambda2
        c2 = tuple(float(v) * lambda1 / lambda2 for v in c1) if same_reference_angle else find_carrier(a2)
    else:
        c2 = carrier2
    o1 = reconstruct(a1, c1, radius, distance, lambda1, pixel_pitch)
    o2 = reconstruct(a2, c2, radius, distance, lambda2, pixel_pitch)
    psi = phase_difference(o1, o2, window=window)
    z = o1 * np.conj(o2)
    num = np.hypot(ndimage.uniform_filter(z.real, window), ndimage.uniform_filter(z.imag, window))
    den = ndimage.uniform_filter(np.abs(o1) * np.abs(o2), window)
    with np.errstate(invalid="ignore", divide="ignore"):
        quality = np.where(den > 0, num / den, 0.0)
    return psi, quality


@grouped_keywords("reconstruction", Reconstruction)
def dual_wavelength_depth(h1, h2, lambda1: float, lambda2: float, reference_depth=None,
                          min_quality: float = 0.0, method: str = "auto",
                          reconstruction: Reconstruction = Reconstruction()) -> HologramDepth:
    """Depth map from two off-axis holograms at two wavelengths (Paper V's chain).

    Parameters
    ----------
    h1, h2 : (H, W) array_like of float
        Holograms at ``lambda1`` and ``lambda2`` (same set-up).
    lambda1, lambda2 : float
        Wavelengths (mm).
    reference_depth : (H, W) array_like or None
        Depth predicted from the CAD model (mm, same zero as the result), used to regularise the
        unwrapping so that steps of more than half a synthetic fringe are recovered; ``None``:
        data-only unwrapping (``method``).
    carrier1, carrier2, radius, distance, pixel_pitch
        As :func:`reconstruct`.  ``carrier1=None``: found in `h1` (:func:`find_carrier`);
        ``carrier2=None``: ``carrier1 * lambda1 / lambda2`` (one reference wave at the same angle
        for both wavelengths, `same_reference_angle`), else found in `h2`.  A carrier error then
        nearly cancels in the phase difference; two independently found carriers leave a
        residual phase tilt (a few thousandths of a cycle per pixel).
    reconstruction : Reconstruction
        Groups ``carrier1``, ``carrier2``, ``radius``, ``distance``, ``pixel_pitch``,
        ``window``, ``same_reference_angle`` (described below); the loose keywords still
        work, with a DeprecationWarning.
    same_reference_angle : bool
        See above.
    window : odd int
        Box over which ``O1 conj(O2)`` is averaged before taking its angle (speckle filter).
    min_quality : float
        Pixels whose speckle quality is below this are left out (NaN).
    method : str
        Unwrapping method (see :func:`shapeverify.phase.unwrap`).

    Returns
    -------
    HologramDepth

    Raises
    ------
    ValueError
        Bad images, shapes that differ, or bad parameters (see :func:`reconstruct`).
    """
    from .regularised import unwrap_data, unwrap_with_reference
    from .wrap import TWO_PI

    a1 = _check_image(h1, "h1")
    a2 = _check_image(h2, "h2")
    if a1.shape != a2.shape:
        raise ValueError(f"h1 and h2 must have the same shape, got {a1.shape} and {a2.shape}")
    Lam = synthetic_wavelength(lambda1, lambda2)
    psi, quality = synthetic_phase(a1, a2, lambda1, lambda2, reconstruction=reconstruction)
    mask = np.isfinite(psi) & (quality >= min_quality)
    if reference_depth is not None:
        ref = np.asarray(reference_depth, dtype=np.float64)
        if ref.shape != a1.shape:
            raise ValueError(f"reference_depth shape {ref.shape} does not match the holograms {a1.shape}")
        mask &= np.isfinite(ref)
        ref_phase = np.where(mask, ref, 0.0) * (TWO_PI * 2.0 / Lam)
        phi = unwrap_with_reference(np.where(mask, psi, np.nan), ref_phase, mask=mask,
                                    method=method).phase
    else:
        phi = unwrap_data(np.where(mask, psi, np.nan), method=method, mask=mask)
    return HologramDepth(depth=phase_to_depth(phi, Lam), psi=psi, phase=phi, quality=quality,
                         synthetic=Lam)


def hologram_file(h1_path, h2_path, out_path, lambda1: float, lambda2: float,
                  reference_path=None, pixel_pitch: float | None = None, distance: float = 0.0,
                  window: int = 5, min_quality: float = 0.0) -> dict:
    """Files in, depth map out: the ``shapeverify hologram`` command.

    Reads two intensity images (``.npy``, grey PNG/TIFF of any bit depth, taken as they are), an
    optional CAD-predicted depth map (``.npy``, mm, NaN = not on the part), runs
    :func:`dual_wavelength_depth` and writes the depth map (``.npy``, mm, NaN = not measured).

    Returns
    -------
    dict
        ``shape``, ``synthetic_wavelength_mm``, ``depth_per_fringe_mm``, ``measured_fraction``,
        ``depth_min_mm``, ``depth_max_mm``, ``median_quality``, ``seconds``, ``output``.

    Raises
    ------
    ValueError
        Unreadable files, wrong shapes, bad parameters (messages say which).
    """
    import time
    from pathlib import Path

    from .holography import depth_per_fringe
    from .files import _read_raw

    t0 = time.perf_counter()
    a1 = _check_image(_read_raw(h1_path), Path(h1_path).name)
    a2 = _check_image(_read_raw(h2_path), Path(h2_path).name)
    ref = None
    if reference_path is not None:
        rp = Path(reference_path)
        if rp.suffix.lower() != ".npy":
            raise ValueError(f"reference depth must be a .npy array of depths in mm, got {rp.name}")
        ref = np.asarray(_read_raw(rp), dtype=np.float64)
    res = dual_wavelength_depth(a1, a2, lambda1, lambda2, reference_depth=ref,
                                min_quality=min_quality, reconstruction=Reconstruction(
                                    distance=distance, pixel_pitch=pixel_pitch, window=window))
    out = Path(out_path)
    if out.suffix.lower() != ".npy":
        raise ValueError(f"output must be a .npy file, got {out.name}")
    np.save(out, res.depth)
    ok = np.isfinite(res.depth)
    return {
        "shape": list(res.depth.shape),
        "synthetic_wavelength_mm": round(res.synthetic, 6),
        "depth_per_fringe_mm": round(depth_per_fringe(res.synthetic), 6),
        "regularised_by_cad": ref is not None,
        "measured_fraction": round(float(ok.mean()), 4),
        "depth_min_mm": float(np.nanmin(res.depth)) if ok.any() else None,
        "depth_max_mm": float(np.nanmax(res.depth)) if ok.any() else None,
        "median_quality": round(float(np.median(res.quality)), 4),
        "seconds": round(time.perf_counter() - t0, 3),
        "output": str(out),
    }
