"""Wrapped phase from ONE fringe image: Fourier-transform profilometry and windowed-Fourier filtering.

A single image of a projected sinusoid is ``I = A + B cos(phi)`` with a carrier: ``phi`` grows by
about ``2*pi`` per fringe period across the image.  Both methods isolate the spectral lobe of
``(B/2) exp(i phi)`` around the carrier frequency and return its angle (the wrapped phase) and
twice its magnitude (the modulation ``B``, the quality map):

* :func:`ftp` -- Takeda, Ina & Kobayashi (1982) with a Gaussian band-pass around the carrier
  peak, applied as demodulation + separable low-pass, normalised by the filtered mask (no FFT
  wrap-around; the image border and masked pixels are edges), with a first-order correction of
  the edge bias.  Fast: one small FFT for the carrier, one separable pass.
* :func:`wff` -- Kemao (2004, 2007): windowed-Fourier filtering; the image is analysed with Gabor
  atoms ``g(x) exp(i xi.x)`` for frequencies ``xi`` around the carrier, small coefficients (noise)
  are set to zero and the rest are synthesised back.  Robust at low fringe contrast; 2 FFTs per
  frequency.

Which lobe is kept decides the sign of the phase: the returned phase increases along
``direction`` (image (u, v) axes).  Masks (True = rejected for that reason): ``saturated``
(clipped pixels, widened by half a period), ``shadow`` (no bright pixel within 0.6 period on both
sides along the carrier: unlit, or outside the lit part), ``low_modulation``; ``mask`` (True =
usable) is the input mask without them and without pixels whose window lies less than
:data:`MIN_SUPPORT` inside the usable area.

References
----------
M. Takeda, H. Ina, S. Kobayashi, J. Opt. Soc. Am. 72 (1982) 156-160.
Q. Kemao, Appl. Opt. 43 (2004) 2695-2702; Opt. Lasers Eng. 45 (2007) 304-317.
Bergström (2011), thesis §3.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft as _fft
from scipy import ndimage

__all__ = ["FringeAnalysis", "ftp", "wff", "find_carrier"]

#: pixels whose Gaussian window is less than this fraction inside the usable mask get no phase
#: (about the outermost 2 px at the default window: their edge bias is not corrected well enough)
MIN_SUPPORT = 0.7


@dataclass(frozen=True, repr=False)
class FringeAnalysis:
    """Result of :func:`ftp` / :func:`wff`.

    Attributes
    ----------
    phase : (H, W) float64
        Wrapped phase in ``(-pi, pi]`` (radians); NaN outside ``mask``.
    modulation : (H, W) float64
        Fringe amplitude ``B`` in image intensity units (>= 0).
    background : (H, W) float64
        Local mean intensity ``A``.
    quality : (H, W) float64
        ``modulation / max(background, eps)`` clipped to [0, 1] (1 = full-contrast fringes); 0 outside mask.
    mask : (H, W) bool
        True where the phase is usable: input mask & lit & not saturated & enough modulation.
    saturated, shadow, low_modulation : (H, W) bool
        The individual rejection reasons (True = rejected for that reason).
    carrier : (2,) float64
        Carrier frequency (cycles per pixel along u, v) of the kept lobe.
    """

    phase: np.ndarray
    modulation: np.ndarray
    background: np.ndarray
    quality: np.ndarray
    mask: np.ndarray
    saturated: np.ndarray
    shadow: np.ndarray
    low_modulation: np.ndarray
    carrier: np.ndarray

    def __repr__(self):
        p = 1.0 / max(float(np.hypot(*self.carrier)), 1e-12)
        return (f"FringeAnalysis(shape={self.phase.shape}, period={p:.3g} px, "
                f"usable={self.mask.mean():.1%})")


def _as_image(image, mask):
    img = np.asarray(image)
    if img.ndim != 2 or min(img.shape) < 8:
        raise ValueError(f"image must be a 2-D array of at least 8 x 8 pixels, got shape {img.shape}")
    full = None
    if np.issubdtype(img.dtype, np.integer):
        full = float(np.iinfo(img.dtype).max)
    f = img.astype(np.float64)
    if not np.all(np.isfinite(f)):
        raise ValueError("image contains NaN or inf")
    if mask is None:
        m = np.ones(img.shape, bool)
    else:
        m = np.asarray(mask, dtype=bool)
        if m.shape != img.shape:
            raise ValueError(f"mask must have the image's shape {img.shape}, got {m.shape}")
    return f, m, full


def _direction(direction):
    d = np.asarray((1.0, 0.0) if direction is None else direction, dtype=np.float64).ravel()
    if d.shape != (2,) or not np.all(np.isfinite(d)) or not np.any(d):
        raise ValueError(f"direction must be a non-zero (2,) vector in image (u, v) axes, got {direction!r}")
    return d / np.linalg.norm(d)


def find_carrier(spectrum_abs, direction=None, min_frequency=None, half=None) -> np.ndarray:
    """Carrier (cycles/pixel, (fu, fv)) = the strongest spectral peak away from DC on the ``direction`` side.

    Parameters
    ----------
    spectrum_abs : (H, W) float
        ``|FFT|`` of the (mean-removed) image, unshifted.
    direction : (2,) or None
        Image-axis vector the phase should increase along (default +u).
    min_frequency : float or None
        Frequencies below this (cycles/pixel) are ignored (default ``4 / min(H, W)``, at least 0.02).
    half : int or None
        Image width when ``spectrum_abs`` is the ``rfft2`` half (H, W//2 + 1) of the spectrum (fu >= 0).
    """
    H, W = spectrum_abs.shape
    Wfull = int(half) if half else W
    d = _direction(direction)
    fv = _fft.fftfreq(H)[:, None]
    fu = (_fft.rfftfreq(Wfull) if half else _fft.fftfreq(W))[None, :]
    fmin = max(4.0 / min(H, Wfull), 0.02) if min_frequency is None else float(min_frequency)
    ok = (fu * d[0] + fv * d[1] > 0) & (np.hypot(fu, fv) >= fmin)
    s = np.where(ok, spectrum_abs, -1.0)
    i, j = np.unravel_index(int(np.argmax(s)), s.shape)
    # sub-bin refinement: centroid of the 3 x 3 neighbourhood
    ii, jj = (np.arange(i - 1, i + 2) % H), np.clip(np.arange(j - 1, j + 2), 0, W - 1)
    w = spectrum_abs[np.ix_(ii, jj)] ** 2
    dv = (w.sum(axis=1) @ np.array([-1.0, 0.0, 1.0])) / w.sum()
    du = (w.sum(axis=0) @ np.array([-1.0, 0.0, 1.0])) / w.sum()
    return np.array([fu[0, j] + du / Wfull, fv[i, 0] + dv / H])


def _saturation(image, saturation, period_px):
    if saturation is None:
        return np.zeros(image.shape, bool)
    sat = image >= saturation
    if sat.any():  # widen by half a period, inside the bounding box of the clipped pixels only
        r = max(1, int(round(period_px / 2)))
        rows, cols = np.flatnonzero(sat.any(axis=1)), np.flatnonzero(sat.any(axis=0))
        box = (slice(max(rows[0] - r, 0), rows[-1] + r + 1), slice(max(cols[0] - r, 0), cols[-1] + r + 1))
        sat[box] = ndimage.binary_dilation(sat[box], structure=np.ones((3, 3), bool), iterations=r)
    return sat


def _window(shape, center, radius, half=False):
    """Raised-cosine window (H, W) over unshifted FFT frequencies around ``center`` (cycles/px).

    ``half``: only the ``rfft2`` columns (fu >= 0), shape (H, W//2 + 1).
    """
    H, W = shape
    fv = _fft.fftfreq(H)[:, None]
    fu = (_fft.rfftfreq(W) if half else _fft.fftfreq(W))[None, :]
    rho = np.hypot(fu - center[0], fv - center[1]) / radius
    return np.where(rho < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(rho, 1.0))), 0.0)


def _premask(f, m_in, full, saturation, carrier, shadow_level):
    """Usable-pixel mask before filtering: input mask, not (near) saturated, lit (a bright fringe
    within 0.6 period on both sides along the carrier)."""
    from . import _fringe_kernels as _fk

    period = 1.0 / float(np.hypot(*carrier))
    level = full if saturation is None else saturation
    sat = _saturation(f, level, period) & m_in
    sub = f[::3, ::3][m_in[::3, ::3]]
    ref = float(np.percentile(sub, 99.5)) if sub.size else 0.0
    lit = np.empty(f.shape, bool)
    _fk.lit_between(np.ascontiguousarray(f), max(1, int(np.ceil(0.6 * period))), shadow_level * ref,
                    bool(abs(carrier[0]) >= abs(carrier[1])), lit)
    shadow = ~lit & m_in
    return m_in & ~sat & ~shadow, sat, shadow


def _assemble(phase, mod, background, m, sat, shadow, min_modulation, carrier):
    sub = (slice(None, None, 3), slice(None, None, 3))
    ms = m[sub]
    bref = float(np.percentile(mod[sub][ms], 95)) if ms.any() else 0.0
    with np.errstate(invalid="ignore"):
        low = m & ((mod < min_modulation * np.maximum(background, 0.0)) | (mod < min_modulation * bref)
                   | ~np.isfinite(phase))
        ok = m & ~low
        q = np.where(ok, np.clip(mod / np.maximum(background, 1e-12), 0.0, 1.0), 0.0)
    return FringeAnalysis(np.where(ok, phase, np.nan), mod, background, q, ok, sat, shadow, low,
                          np.asarray(carrier, dtype=np.float64))


def _prepare(f, m):
    if m.all():
        mean = float(f.mean())
        return f - mean, mean
    mean = float(f[m].mean()) if m.any() else 0.0
    return np.where(m, f - mean, 0.0), mean


def _carrier(f, m, carrier):
    """Carrier of the fu >= 0 half (cycles/pixel)."""
    if carrier is None:
        g, _ = _prepare(f, m)
        return find_carrier(np.abs(_fft.rfft2(g, workers=1)), direction=(1.0, 0.0), half=f.shape[1])
    c = np.asarray(carrier, dtype=np.float64)
    if c.shape != (2,) or not np.all(np.isfinite(c)) or not 0 < np.hypot(*c) < 0.5 * np.sqrt(2):
        raise ValueError(f"carrier must be a finite non-zero (2,) frequency in cycles/pixel, got {carrier!r}")
    return -c if (c[0] < 0 or (c[0] == 0 and c[1] < 0)) else c


def ftp(image, mask=None, carrier=None, direction=None, sigma=None, saturation=None, shadow_level=0.1,
        min_modulation=0.15, edge_correction=True) -> FringeAnalysis:
    """Fourier-transform profilometry of one fringe image (Takeda et al. 1982).

    The side lobe around the carrier ``c`` is isolated with a Gaussian band-pass
    ``exp(-2 pi^2 sigma^2 |f - c|^2)``.  It is applied as Takeda's demodulation: the image
    (mean removed, masked pixels zero) times ``exp(-2 pi i c.x)``, low-passed by the Gaussian of
    width ``sigma`` as a separable convolution -- the same filter as in the Fourier domain, but
    without the FFT's wrap-around, and normalised by the filtered mask so that the image border and
    masked pixels are edges, not data.  Near an edge the truncated window biases the phase by
    (local residual frequency) x (offset of the window's valid centroid); ``edge_correction``
    subtracts that first-order term.

    Parameters
    ----------
    image : (H, W) array_like
        Intensities (uint8, uint16 or float).
    mask : (H, W) bool or None
        Pixels to use (True).
    carrier : (2,) float or None
        Carrier frequency (cycles/pixel, (fu, fv)); ``None``: the spectral peak (:func:`find_carrier`).
    direction : (2,) float or None
        The returned phase increases along this image direction (default +u, i.e. to the right).
    sigma : float or None
        Gaussian window width in pixels (default 0.6 fringe period).
    saturation : float or None
        Clipping level; default the integer dtype's maximum (none for float images).  Saturated
        pixels and those within half a period of them are rejected.
    shadow_level : float
        Shadow (or outside the lit part): no pixel brighter than this fraction of the image's
        99.5th percentile within 0.6 period on both sides along the carrier.
    min_modulation : float
        Low modulation: ``B < min_modulation * A`` or below this fraction of the 95th percentile of ``B``.
    edge_correction : bool
        Apply the first-order edge correction.

    Returns
    -------
    FringeAnalysis

    Examples
    --------
    >>> v, u = np.mgrid[0:64, 0:96]
    >>> phi = 2 * np.pi * u / 8.0 + 0.0005 * (u - 48.0) ** 2
    >>> r = ftp(100 + 80 * np.cos(phi))
    >>> err = np.angle(np.exp(1j * (r.phase - phi)))[r.mask]
    >>> bool(np.abs(err).max() < 0.05)
    True
    """
    from . import _fringe_kernels as _fk

    f, m_in, full = _as_image(image, mask)
    d = _direction(direction)
    c = _carrier(f, m_in, carrier)
    period = 1.0 / float(np.hypot(*c))
    s = 0.6 * period if sigma is None else float(sigma)
    if not s > 0:
        raise ValueError(f"sigma must be positive (pixels), got {sigma}")
    m, sat, shadow = _premask(f, m_in, full, saturation, c, shadow_level)
    H, W = f.shape
    R = int(np.ceil(3.0 * s))
    k = np.arange(-R, R + 1, dtype=np.float64)
    g = np.exp(-0.5 * (k / s) ** 2)
    g /= g.sum()
    xg = k * g if edge_correction else np.zeros_like(g)
    mean = float(f[m].mean()) if m.any() else 0.0
    # work inside the bounding box of the usable pixels (plus the window): the rest has no phase
    phase, mod, background = np.full((H, W), np.nan), np.zeros((H, W)), np.zeros((H, W))
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    if len(rows):
        bi = slice(max(rows[0] - R, 0), min(rows[-1] + R + 1, H))
        bj = slice(max(cols[0] - R, 0), min(cols[-1] + R + 1, W))
        h, w = bi.stop - bi.start, bj.stop - bj.start
        au = -2 * np.pi * c[0] * np.arange(bj.start, bj.stop)
        av = -2 * np.pi * c[1] * np.arange(bi.start, bi.stop)
        f32 = np.float32  # single precision: half the memory traffic; phase error ~1e-6 rad
        out = [np.empty((h, w), f32) for _ in range(6)]
        _fk.demodulate(np.ascontiguousarray(f[bi, bj], dtype=f32), np.ascontiguousarray(m[bi, bj]), f32(mean),
                       np.cos(au).astype(f32), np.sin(au).astype(f32), np.cos(av).astype(f32),
                       np.sin(av).astype(f32), g.astype(f32), xg.astype(f32), *out)
        re, im, a, m0, mx, my = out
        theta, ph, md = np.empty((h, w)), np.empty((h, w)), np.empty((h, w))
        _fk.edge_corrected_phase(re, im, m0, mx, my, c[0], c[1], bi.start, bj.start, MIN_SUPPORT, theta, ph, md)
        phase[bi, bj], mod[bi, bj] = ph, md
        with np.errstate(divide="ignore", invalid="ignore"):
            background[bi, bj] = np.where(m0 > 1e-6, a / m0, 0.0)
    if c @ d < 0:  # the phase must increase along `direction`
        phase = -phase
        c = -c
    return _assemble(phase, mod, background, m, sat, shadow, min_modulation, c)


def wff(image, mask=None, carrier=None, direction=None, sigma=None, bandwidth=0.6, threshold=None,
        saturation=None, shadow_level=0.1, min_modulation=0.15) -> FringeAnalysis:
    """Windowed-Fourier filtering of one fringe image (Kemao 2004, 2007).

    The frequencies ``xi`` form a grid (step ``1/sigma`` rad/pixel) over the disc of radius
    ``bandwidth * |carrier|`` around the carrier; coefficients ``|Sf(x, xi)| < threshold`` are
    dropped; the synthesis is normalised by ``sum_xi |G_xi|^2`` per frequency, so that clean fringes
    pass unchanged.

    Parameters
    ----------
    image, mask, carrier, direction, bandwidth, saturation, shadow_level, min_modulation :
        As in :func:`ftp`.
    sigma : float or None
        Gaussian window width (pixels); default one fringe period.
    threshold : float or None
        Coefficient threshold (intensity units of ``B/2``); default 10 x the coefficient noise
        (image noise from Immerkaer's estimator times the atom's norm).

    Returns
    -------
    FringeAnalysis
    """
    f, m_in, full = _as_image(image, mask)
    dvec = _direction(direction)
    c = _carrier(f, m_in, carrier)
    fc = float(np.hypot(*c))
    m, sat, shadow = _premask(f, m_in, full, saturation, c, shadow_level)
    g, mean = _prepare(f, m)
    H, W = f.shape
    F = _fft.fft2(g, workers=1)
    s = 1.0 / fc if sigma is None else float(sigma)
    if not s > 0:
        raise ValueError(f"sigma must be positive (pixels), got {sigma}")
    wu = 2 * np.pi * _fft.fftfreq(W)[None, :]
    wv = 2 * np.pi * _fft.fftfreq(H)[:, None]
    c_w = 2 * np.pi * c
    rad = 2 * np.pi * bandwidth * fc
    step = 1.0 / s
    n = int(np.ceil(rad / step))
    grid = [(c_w[0] + i * step, c_w[1] + j * step) for i in range(-n, n + 1) for j in range(-n, n + 1)
            if i * i + j * j <= n * n]

    def atom(xi):
        return np.exp(-0.5 * s * s * ((wu - xi[0]) ** 2 + (wv - xi[1]) ** 2))

    if threshold is None:
        # 10 x the coefficient noise: image noise (Immerkaer 1996; the product of second
        # differences hardly responds to fringes along one axis) times the atom's norm
        lap = ndimage.convolve(f, np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], float), mode="reflect")
        sigma_n = np.sqrt(np.pi / 2) * float(np.abs(lap[1:-1, 1:-1][m[1:-1, 1:-1]]).mean()) / 6.0 if m.any() else 0.0
        thr = 10.0 * sigma_n / np.sqrt(4 * np.pi * s * s)
    else:
        thr = float(threshold)
    acc = np.zeros((H, W), complex)
    norm = np.zeros((H, W))
    for xi in grid:
        G = atom(xi)
        S = _fft.ifft2(F * G, workers=1)
        S[np.abs(S) < thr] = 0.0
        acc += _fft.fft2(S, workers=1) * G
        norm += G * G
    keep = norm > 1e-3 * norm.max()
    acc = np.where(keep, acc / np.where(keep, norm, 1.0), 0.0)
    analytic = _fft.ifft2(acc, workers=1)
    low = _fft.ifft2(F * _window(f.shape, (0.0, 0.0), bandwidth * fc), workers=1).real + mean
    phase, mod = np.angle(analytic), 2.0 * np.abs(analytic)
    if c @ dvec < 0:
        phase, c = -phase, -c
    return _assemble(phase, mod, low, m, sat, shadow, min_modulation, c)
