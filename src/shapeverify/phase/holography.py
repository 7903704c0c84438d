"""Dual-wavelength holography: synthetic wavelength, phase difference, phase <-> depth (Paper V).

Model and assumptions (thesis Ch. 3.2; Paper V Sec. 2-3 as far as the thesis text describes it)
-----------------------------------------------------------------------------------------------
* Each hologram ``h_k`` (k = 1, 2) is the complex object field recorded at wavelength
  ``lambda_k``; its phase is ``2*pi*L / lambda_k + c_k`` where ``L`` is the optical path length
  from the illumination source to the surface point and on to the camera, and ``c_k`` a
  constant of the set-up.
* The phase of ``h1 * conj(h2)`` is then ``2*pi*L / Lambda + c`` (modulo ``2*pi``) with the
  synthetic wavelength ``Lambda = lambda1 * lambda2 / |lambda1 - lambda2|`` (Paper V eq. 4), for
  ``lambda1 < lambda2``.  With ``lambda1 > lambda2`` the sign flips; :func:`phase_difference`
  takes the holograms in the order you give them -- pass the shorter wavelength first.
* One fringe (a phase change of ``2*pi``) is a change of ``Lambda`` in the optical path.  With
  illumination and viewing along the same direction (the thesis set-up: "illumination direction
  and view point direction is the same"), the path is travelled twice, so one fringe is a depth
  step ``delta = Lambda / 2`` (Paper V eq. 3; the thesis quotes 0.20 mm per fringe for its set-up).
  For illumination at an angle ``theta`` to the viewing direction the sensitivity drops to
  ``delta = Lambda / (2 cos(theta / 2))`` (the standard sensitivity-vector result, collimated
  light).
* Divergent illumination (Paper V Fig. 4, "perspective geometry"): the light comes from a point
  source ``S`` and is observed through a pinhole camera with centre ``C``.  For the pixel whose
  viewing ray is ``X = C + r * d`` (``d`` unit), ``L = |X - S| + |X - C| = |C - S + r d| + r``.
  Given ``L`` from the unwrapped phase, ``r`` has the closed form
  ``r = (L**2 - |a|**2) / (2 * (L + a . d))`` with ``a = C - S``; for a source at the camera
  centre ``r = L / 2`` (then a plane parallel to the detector gives circular fringes, as the
  thesis notes).
* The absolute path length is unknown from a phase map: it is ``L = Lambda * phi / (2*pi) +
  path_offset``, where `path_offset` (the path at zero phase) must come from calibration or
  from registration to the CAD model (Paper V fixes it through the model).
* Lengths in millimetres (wavelengths too: 633 nm = 633e-6 mm).  Polarisation, dispersion between
  the two wavelengths, refraction and speckle decorrelation are ignored.

References
----------
Bergström (2011), thesis Ch. 3.2 and Paper V (eqs. 3-4, Fig. 4); U. Schnars, W. Jüptner,
*Digital Holography*, Springer 2005, Ch. 5 (multi-wavelength contouring).
"""

from __future__ import annotations

import numpy as np

from .wrap import TWO_PI, wrap

__all__ = ["synthetic_wavelength", "depth_per_fringe", "phase_difference", "phase_to_depth",
           "phase_to_points", "points_to_phase"]


def synthetic_wavelength(lambda1: float, lambda2: float) -> float:
    """Synthetic wavelength ``Lambda = lambda1 * lambda2 / |lambda1 - lambda2|`` (Paper V eq. 4).

    Parameters
    ----------
    lambda1, lambda2 : float > 0
        The two wavelengths (any length unit; the result has the same unit).

    Raises
    ------
    ValueError
        Non-positive, non-finite or equal wavelengths.

    Examples
    --------
    >>> round(synthetic_wavelength(632.8e-6, 633.8e-6), 4)    # mm
    0.4011
    """
    l1, l2 = float(lambda1), float(lambda2)
    if not (np.isfinite(l1) and np.isfinite(l2) and l1 > 0 and l2 > 0):
        raise ValueError(f"wavelengths must be finite and > 0, got {lambda1!r} and {lambda2!r}")
    if l1 == l2:
        raise ValueError("the two wavelengths are equal: the synthetic wavelength is infinite")
    return l1 * l2 / abs(l1 - l2)


def depth_per_fringe(synthetic: float, angle: float = 0.0) -> float:
    """Depth change per fringe (``2*pi`` of phase): ``Lambda / (2 cos(angle / 2))``.

    Parameters
    ----------
    synthetic : float > 0
        Synthetic wavelength ``Lambda``.
    angle : float
        Angle (radians) between the illumination direction and the viewing direction; 0 for
        the thesis set-up (Paper V eq. 3: ``delta = Lambda / 2``).

    Raises
    ------
    ValueError
        Non-positive `synthetic`, or ``|angle| >= pi``.
    """
    s = float(synthetic)
    if not (np.isfinite(s) and s > 0):
        raise ValueError(f"synthetic wavelength must be finite and > 0, got {synthetic!r}")
    if not abs(angle) < np.pi:
        raise ValueError(f"angle must be in (-pi, pi) radians, got {angle!r}")
    return s / (2.0 * np.cos(angle / 2.0))


def phase_difference(h1, h2, window: int = 1):
    """Wrapped phase of ``h1 * conj(h2)``: the phase map at the synthetic wavelength.

    Parameters
    ----------
    h1, h2 : (H, W) complex array_like
        Complex holograms (reconstructed object fields) at ``lambda1 < lambda2``.
    window : odd int >= 1
        Average ``h1 * conj(h2)`` over a ``window x window`` box before taking the angle (a
        standard speckle-noise filter; 1 = none).

    Returns
    -------
    psi : (H, W) float64 in ``(-pi, pi]``; NaN where either hologram is 0 or not finite.

    Raises
    ------
    ValueError
        Shapes differ or are not 2-D, or `window` is not a positive odd integer.
    """
    a = np.asarray(h1)
    b = np.asarray(h2)
    if a.ndim != 2 or a.shape != b.shape:
        raise ValueError(f"holograms must be 2-D arrays of the same shape, got {a.shape} and {b.shape}")
    if int(window) != window or window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd integer, got {window!r}")
    z = a.astype(np.complex128) * np.conj(b.astype(np.complex128))
    bad = ~np.isfinite(z) | (z == 0)
    z[bad] = 0.0
    if window > 1:
        from scipy import ndimage
        zr = ndimage.uniform_filter(z.real, window, mode="constant")
        zi = ndimage.uniform_filter(z.imag, window, mode="constant")
        z = zr + 1j * zi
    psi = wrap(np.angle(z))
    psi[bad] = np.nan
    return psi


def phase_to_depth(phi, synthetic: float, angle: float = 0.0):
    """Depth from unwrapped phase for collimated light: ``phi / (2*pi) * depth_per_fringe``.

    Parameters
    ----------
    phi : array_like of float
        Unwrapped phase (radians); the zero of depth is where ``phi = 0``.
    synthetic, angle
        As :func:`depth_per_fringe`.

    Returns
    -------
    depth : float64 array like `phi` (NaN stays NaN), in the unit of `synthetic`; it grows with
    the optical path (away from the camera).
    """
    return np.asarray(phi, dtype=np.float64) / TWO_PI * depth_per_fringe(synthetic, angle)


def _check_geometry(directions, center, source):
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ValueError(f"directions must have shape (..., 3), got {d.shape}")
    nrm = np.linalg.norm(d, axis=-1, keepdims=True)
    if not np.all(np.isfinite(d)) or np.any(nrm == 0):
        raise ValueError("directions must be finite and non-zero")
    d = d / nrm
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center must be a finite (3,) point, got shape {c.shape}")
    s = c if source is None else np.asarray(source, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)):
        raise ValueError(f"source must be a finite (3,) point or None, got shape {s.shape}")
    return d, c, s


def phase_to_points(phi, synthetic: float, directions, center=(0.0, 0.0, 0.0), source=None,
                    path_offset: float = 0.0):
    """3-D points from unwrapped phase in the divergent-illumination (perspective) geometry.

    Parameters
    ----------
    phi : (...) array_like of float
        Unwrapped phase per pixel (NaN = no measurement).
    synthetic : float > 0
        Synthetic wavelength ``Lambda`` (mm).
    directions : (..., 3) array_like
        Viewing ray of each pixel (normalised here), same leading shape as `phi`.
    center : (3,) array_like
        Camera centre ``C`` (start of the rays).
    source : (3,) array_like or None
        Point source of the divergent illumination ``S``; ``None``: at the camera centre
        (illumination along the viewing direction, the thesis set-up).
    path_offset : float
        Optical path length ``L`` (mm) at zero phase: ``L = Lambda * phi / (2*pi) + path_offset``.

    Returns
    -------
    points : (..., 3) float64
        ``C + r * d``; NaN where `phi` is NaN or the path is too short to reach the ray
        (``L <= |C - S|`` or a negative range).

    Raises
    ------
    ValueError
        Bad shapes or non-finite geometry.

    Examples
    --------
    >>> d = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    >>> X = np.array([[0.0, 0.0, 100.0], [30.0, 0.0, 40.0]])
    >>> phi = points_to_phase(X, 0.4, source=(10.0, 0.0, 0.0))
    >>> bool(np.allclose(phase_to_points(phi, 0.4, d, source=(10.0, 0.0, 0.0)), X))
    True
    """
    ph = np.asarray(phi, dtype=np.float64)
    d, c, s = _check_geometry(directions, center, source)
    if d.shape[:-1] != ph.shape:
        raise ValueError(f"directions shape {d.shape} does not match phi shape {ph.shape} + (3,)")
    if not (np.isfinite(synthetic) and synthetic > 0):
        raise ValueError(f"synthetic wavelength must be finite and > 0, got {synthetic!r}")
    L = synthetic * ph / TWO_PI + float(path_offset)
    a = c - s
    a2 = float(a @ a)
    ad = d @ a
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (L * L - a2) / (2.0 * (L + ad))
        ok = np.isfinite(r) & (L > np.sqrt(a2)) & (r >= 0)
    r = np.where(ok, r, np.nan)
    return c + r[..., None] * d


def points_to_phase(points, synthetic: float, center=(0.0, 0.0, 0.0), source=None,
                    path_offset: float = 0.0):
    """Unwrapped phase of surface points: ``2*pi * (|X - S| + |X - C| - path_offset) / Lambda``.

    The forward model of :func:`phase_to_points` (use it to predict the phase of CAD points).

    Parameters
    ----------
    points : (..., 3) array_like
    synthetic, center, source, path_offset
        As :func:`phase_to_points`.

    Returns
    -------
    phi : (...) float64
    """
    X = np.asarray(points, dtype=np.float64)
    if X.ndim < 1 or X.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3), got {X.shape}")
    _, c, s = _check_geometry(np.array([0.0, 0.0, 1.0]), center, source)
    if not (np.isfinite(synthetic) and synthetic > 0):
        raise ValueError(f"synthetic wavelength must be finite and > 0, got {synthetic!r}")
    L = np.linalg.norm(X - s, axis=-1) + np.linalg.norm(X - c, axis=-1)
    return TWO_PI * (L - float(path_offset)) / synthetic
