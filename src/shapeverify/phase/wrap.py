"""Wrapping, 1-D unwrapping, residues and the input checks shared by the 2-D unwrappers.

Conventions (thesis Ch. 4.1)
----------------------------
The wrapping operator ``W`` maps a phase onto one period of length ``2*pi``:

* eq. (1) ``W(phi) = atan2(sin(phi), cos(phi))``, range ``(-pi, pi]`` (``convention="atan2"``,
  the default; ``np.angle`` uses it too);
* eq. (2) ``W(phi) = ((phi + pi) mod 2*pi) - pi``, range ``[-pi, pi)`` (``convention="modulo"``).

The two agree except at ``phi = pi + 2*pi*n``, where eq. (1) gives ``pi`` and eq. (2) gives ``-pi``.
Both are evaluated here with exact modular arithmetic (not with ``sin``/``cos``), so the result at
the boundary is the mathematical one and large phases lose no accuracy to ``sin`` rounding.

Unwrapping finds the integer field ``n`` of eq. (3), ``phi = psi + 2*pi*n``.  Every unwrapper in
this package returns a *congruent* result (``phi - psi`` is an exact multiple of ``2*pi`` up to
rounding at every valid pixel) unless documented otherwise.

Masks: a mask is a boolean ``(H, W)`` array that is ``True`` where the phase is VALID (note:
scikit-image's masked arrays use the opposite sense).  Unwrapped results are ``NaN`` outside it.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi

__all__ = ["wrap", "unwrap_1d", "residues", "TWO_PI"]


def wrap(phi, convention: str = "atan2"):
    """Wrap a phase onto one period (thesis eq. 1 or eq. 2).

    Parameters
    ----------
    phi : array_like of float
        Phase in radians, any shape.  NaN stays NaN.
    convention : {"atan2", "modulo"}
        ``"atan2"``: thesis eq. (1), range ``(-pi, pi]``.
        ``"modulo"``: thesis eq. (2), range ``[-pi, pi)``.

    Returns
    -------
    ndarray of float64 (same shape as `phi`; a 0-d array for a scalar input)

    Raises
    ------
    ValueError
        If `convention` is unknown.

    References
    ----------
    Bergström (2011), thesis Ch. 4.1, eqs. (1)-(2).

    Examples
    --------
    >>> float(wrap(np.pi)), float(wrap(np.pi, convention="modulo"))
    (3.141592653589793, -3.141592653589793)
    >>> float(wrap(7.0))  # 7 - 2*pi
    0.7168146928204138
    """
    x = np.asarray(phi, dtype=np.float64)
    if convention == "atan2":
        # (-pi, pi]:  pi - ((pi - x) mod 2pi), with (pi - x) mod 2pi in [0, 2pi)
        r = np.mod(np.pi - x, TWO_PI)
        r = np.where(r >= TWO_PI, 0.0, r)  # np.mod may round up to exactly 2pi
        return np.pi - r
    if convention == "modulo":
        r = np.mod(x + np.pi, TWO_PI)
        r = np.where(r >= TWO_PI, 0.0, r)
        return r - np.pi
    raise ValueError(f"convention must be 'atan2' (thesis eq. 1) or 'modulo' (eq. 2), got {convention!r}")


def unwrap_1d(psi):
    """Unwrap a univariate phase by integrating wrapped differences (thesis Ch. 4.1).

    The first sample keeps its value; every later sample is the previous unwrapped value plus the
    wrapped difference ``W(psi[k] - psi[k-1])``.  This recovers the original phase exactly when
    it has no jumps of magnitude ``>= pi`` (thesis Fig. 6); otherwise it fails as in Fig. 7 --
    use a reference phase then (:func:`shapeverify.phase.unwrap_with_reference`).

    Parameters
    ----------
    psi : (N,) array_like of float
        Wrapped phase (any values; only differences modulo ``2*pi`` matter).  Must be finite.

    Returns
    -------
    phi : (N,) float64, congruent with `psi`.

    Raises
    ------
    ValueError
        If `psi` is not 1-D, is empty, or holds NaN/inf.

    Examples
    --------
    >>> x = np.linspace(0.0, 12.0, 50)
    >>> bool(np.allclose(unwrap_1d(wrap(x)), x))
    True
    """
    p = np.asarray(psi, dtype=np.float64)
    if p.ndim != 1:
        raise ValueError(f"unwrap_1d needs a 1-D array, got shape {p.shape}; use unwrap() for 2-D phase maps")
    if p.size == 0:
        raise ValueError("unwrap_1d got an empty array")
    if not np.all(np.isfinite(p)):
        bad = int(np.count_nonzero(~np.isfinite(p)))
        raise ValueError(f"unwrap_1d: psi has {bad} NaN/inf samples; remove or interpolate them first")
    d = wrap(np.diff(p))
    out = np.empty_like(p)
    out[0] = p[0]
    np.cumsum(d, out=out[1:])
    out[1:] += p[0]
    # make the result exactly congruent with psi (remove the rounding drift of the cumulative sum)
    out[1:] = p[1:] + TWO_PI * np.round((out[1:] - p[1:]) / TWO_PI)
    return out


def residues(psi, mask=None):
    """Residue charges of a wrapped phase map (Ghiglia & Pritt 1998, Ch. 2.5).

    The charge of the elementary 2x2 loop with top-left pixel ``(i, j)`` is the sum of the wrapped
    differences around it divided by ``2*pi`` (``+1``, ``-1`` or ``0``).  A residue-free map is
    unwrapped path-independently; residues mark noise or discontinuities.

    Parameters
    ----------
    psi : (H, W) float64 wrapped phase.
    mask : (H, W) bool or None
        True where valid; loops touching an invalid pixel get charge 0.

    Returns
    -------
    charge : (H-1, W-1) int8
    """
    p = np.asarray(psi, dtype=np.float64)
    if p.ndim != 2:
        raise ValueError(f"residues needs a 2-D phase map, got shape {p.shape}")
    with np.errstate(invalid="ignore"):
        dx = wrap(np.diff(p, axis=1))  # (H, W-1)
        dy = wrap(np.diff(p, axis=0))  # (H-1, W)
        s = dx[:-1, :] + dy[:, 1:] - dx[1:, :] - dy[:, :-1]
    q = np.rint(s / TWO_PI)
    valid = np.isfinite(q)
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        valid &= m[:-1, :-1] & m[1:, :-1] & m[:-1, 1:] & m[1:, 1:]
    return np.where(valid, q, 0).astype(np.int8)


def check_phase_map(psi, mask=None, name: str = "psi"):
    """Validate a wrapped phase map and its mask at the public boundary.

    Returns ``(psi_float64, mask_bool)`` where NaN pixels of `psi` are set to 0 and excluded
    from the mask.  With ``mask=None`` NaN pixels are treated as masked; with an explicit mask,
    NaN at a pixel the mask calls valid is an error (the two disagree about that pixel).

    Raises
    ------
    ValueError
        Not 2-D, too small, +-inf values, NaN inside an explicit mask, wrong mask shape or dtype,
        or no valid pixel at all.
    """
    p = np.asarray(psi)
    if p.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be a real-valued array, got dtype {p.dtype}")
    # C order: a Fortran-ordered map (np.load of a .npy written in Fortran order) kept its
    # order through astype and made numba compile the least-squares kernels again for it
    p = p.astype(np.float64, order="C", copy=True)
    if p.ndim != 2:
        raise ValueError(
            f"{name} must be a 2-D phase map (H, W), got shape {p.shape}; "
            "for 1-D signals use unwrap_1d, for stacks unwrap each image")
    if p.shape[0] < 2 or p.shape[1] < 2:
        raise ValueError(f"{name} must be at least 2 x 2 pixels, got shape {p.shape}")
    if np.isinf(p).any():
        raise ValueError(f"{name} holds {int(np.isinf(p).sum())} infinite values; "
                         "mask them (mask=...) or set them to NaN")
    nan = np.isnan(p)
    if mask is None:
        m = ~nan
    else:
        m_in = np.asarray(mask)
        if m_in.shape != p.shape:
            raise ValueError(f"mask shape {m_in.shape} does not match {name} shape {p.shape}; "
                             "the mask must be a boolean (H, W) array, True where valid")
        if m_in.dtype != bool:
            if m_in.dtype.kind not in "iu" or not np.isin(m_in, (0, 1)).all():
                raise ValueError(f"mask must be boolean (True = valid pixel), got dtype {m_in.dtype}")
        m = m_in.astype(bool, order="C")
        bad = nan & m
        if bad.any():
            raise ValueError(
                f"{name} has NaN at {int(bad.sum())} pixels that the mask marks valid; "
                "set mask &= ~np.isnan(psi) or pass mask=None to treat NaN as masked")
    if not m.any():
        raise ValueError(f"no valid pixel in {name}: the mask (and NaN pixels) exclude the whole map")
    p[~m] = 0.0
    return p, m


def check_map_like(x, shape, name: str, mask=None, allow_nan_outside_mask: bool = True):
    """Validate an auxiliary (H, W) map (quality, reference) against the phase map's shape."""
    a = np.asarray(x)
    if a.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be a real-valued array, got dtype {a.dtype}")
    a = a.astype(np.float64, order="C", copy=True)
    if a.shape != tuple(shape):
        raise ValueError(f"{name} shape {a.shape} does not match the phase map shape {tuple(shape)}")
    finite = np.isfinite(a)
    region = mask if mask is not None else np.ones(a.shape, bool)
    bad = region & ~finite
    if bad.any():
        raise ValueError(
            f"{name} has {int(bad.sum())} NaN/inf values at valid pixels; "
            f"exclude them from the mask (mask &= np.isfinite({name})) or fill them")
    if allow_nan_outside_mask:
        a[~finite] = 0.0
    return a
