"""Quality-guided path-following unwrapping (reliability sorting, Herráez et al. 2002).

Two public functions:

* :func:`unwrap_quality` -- the Herráez algorithm: every pixel gets a reliability (the inverse of
  its second-difference magnitude, or a user quality map), every edge between 4-neighbours the sum
  of its pixels' reliabilities, and edges are processed from the most to the least reliable,
  merging groups of already unwrapped pixels (a noncontinuous path).  Exact (up to a constant
  ``2*pi*k`` per connected region) on residue-free data; fast (O(N), counting sort).
* :func:`unwrap_filtered` -- the default of :func:`shapeverify.phase.unwrap`: the wrapped phase is
  smoothed in the complex domain (``exp(i*psi)`` averaged over a small window), the smooth map,
  which has almost no residues, is unwrapped by reliability sorting, and the result is made
  congruent with the data: ``phi = phi_s + W(psi - phi_s)``.  Every pixel keeps its measured
  value modulo ``2*pi``; only the multiple ``n`` comes from the smoothed map.  This is far more
  robust to noise than reliability sorting on the raw data (see benchmarks/results_phase.md), and
  it is exact on noise-free data because a residue-free map skips the smoothing.

References
----------
M. A. Herráez et al., Appl. Opt. 41 (2002) 7437-7444.
D. C. Ghiglia, M. D. Pritt, *Two-Dimensional Phase Unwrapping*, Wiley 1998, Ch. 4 (quality maps,
congruence).
"""

from __future__ import annotations

import logging

import numpy as np
from . import _kernels
from .wrap import TWO_PI, check_map_like, check_phase_map, wrap

log = logging.getLogger(__name__)

__all__ = ["unwrap_quality", "unwrap_filtered", "smooth_wrapped", "pseudo_correlation"]

_NBINS = 1 << 16


def _path_follow(psi, mask, rel):
    """Integer field n (H, W) for validated input; psi in [-pi, pi]; rel (H, W) >= 0, higher = better."""
    H, W = psi.shape
    costs = _kernels.edge_costs(rel, mask)
    sample = costs[:: max(1, costs.size // 100_000)]
    sample = sample[(sample > 0) & np.isfinite(sample)]
    scale = float(np.median(sample)) if sample.size else 1.0
    order = _kernels.bucket_order(costs, scale, _NBINS)
    n = _kernels.merge_edges(_kernels.edge_jumps(psi, mask), order, H, W)
    return n.reshape(H, W)


def _principal(p):
    """p itself when it already lies in [-pi, pi], else its wrapped value (congruent)."""
    if p.size and (p.min() < -np.pi or p.max() > np.pi):
        return wrap(p)
    return p


def _reliability(psi, mask, quality):
    """Pixel reliability >= 0: 1 / second difference (Herráez), or the quality shifted to >= 0."""
    if quality is None:
        with np.errstate(divide="ignore"):
            return 1.0 / _kernels.second_difference(psi, mask)
    qmin = float(quality[mask].min())
    return np.where(mask, quality - qmin, 0.0)


def _finish(psi, mask, n):
    phi = psi + TWO_PI * n
    phi[~mask] = np.nan
    return phi


def unwrap_quality(psi, mask=None, quality=None):
    """Reliability-sorting path-following unwrapping (Herráez et al. 2002).

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians (any period offset; only values modulo ``2*pi`` matter).
    mask : (H, W) bool or None
        True where the phase is valid.  ``None``: NaN pixels are masked, all others valid.
    quality : (H, W) array_like of float or None
        Pixel quality, higher = more reliable (e.g. fringe modulation).  ``None``: Herráez's
        reliability, the inverse second-difference magnitude of `psi`.

    Returns
    -------
    phi : (H, W) float64
        Unwrapped phase, congruent with `psi` (``phi - psi`` is a multiple of ``2*pi``), NaN
        outside the mask.  Each 4-connected region of the mask is unwrapped on its own; its most
        reliable group keeps the wrapped value (its ``2*pi*k`` offset is arbitrary).

    Raises
    ------
    ValueError
        `psi` not 2-D, infinite values, NaN inside an explicit mask, mask or quality of the wrong
        shape, quality not finite on valid pixels, or no valid pixel.

    References
    ----------
    M. A. Herráez et al., Appl. Opt. 41 (2002) 7437-7444.

    Examples
    --------
    >>> y, x = np.mgrid[0:64, 0:64]
    >>> true = 0.02 * ((x - 30.0) ** 2 + (y - 20.0) ** 2)
    >>> phi = unwrap_quality(wrap(true))
    >>> bool(np.allclose(phi - phi[30, 20], true - true[30, 20]))
    True
    """
    p, m = check_phase_map(psi, mask)
    q = None if quality is None else check_map_like(quality, p.shape, "quality", m)
    p = _principal(p)
    return _finish(p, m, _path_follow(p, m, _reliability(p, m, q)))


def smooth_wrapped(psi, mask, window: int, parts=None):
    """Average ``exp(i*psi)`` over a ``window x window`` box (normalised for the mask).

    Returns ``(psi_s, coherence)``: the phase of the average and its magnitude divided by the
    number of valid pixels in the window (1 for a locally constant phase, about
    ``exp(-sigma**2 / 2)`` for phase noise of standard deviation ``sigma``).  `parts` may pass
    precomputed ``_kernels.phasor_parts(psi, mask)``.  Trusts its input.
    """
    c, s, mf = _kernels.phasor_parts(psi, mask) if parts is None else parts
    r = window // 2
    cs = _kernels.box_sum(c, r)
    ss = _kernels.box_sum(s, r)
    cnt = _kernels.box_sum(mf, r)
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(cnt > 0.5, np.hypot(cs, ss) / np.maximum(cnt, 1.0), 0.0)
    return np.arctan2(ss, cs), coherence


def pseudo_correlation(psi, mask=None, window: int = 3):
    """Pseudo-correlation quality map: ``|mean of exp(i*psi)|`` over a ``window x window`` box.

    1 where the phase is locally constant, lower where it is noisy or changes fast (Ghiglia &
    Pritt 1998, Ch. 3.3).  Use it as ``quality=`` (path order) or as weights for ``"wls"``/``"lp"``.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase.
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels masked); masked pixels get 0.
    window : odd int >= 1

    Returns
    -------
    quality : (H, W) float64 in [0, 1]
    """
    p, m = check_phase_map(psi, mask)
    w = int(window)
    if w < 1 or w % 2 == 0 or w != window:
        raise ValueError(f"window must be a positive odd integer, got {window!r}")
    _, coh = smooth_wrapped(p, m, w)
    return np.where(m, np.clip(coh, 0.0, 1.0), 0.0)


def _auto_window(psi, mask):
    """Smoothing window from the residue density and the local phase gradient.

    Returns ``(window, residue density, phasor parts or None)``.
    """
    n_valid = max(int(mask.sum()), 1)
    density = _kernels.count_residues(psi, mask) / n_valid
    if density < 1e-4:
        return 1, density, None
    parts = _kernels.phasor_parts(psi, mask)
    w = 7 if density > 1e-2 else (5 if density > 1e-3 else 3)
    # keep the phase change across the window below 1.4 pi: local gradient from lag-one phasor
    # products averaged over 5 x 5 boxes (noise cancels), on a grid of every 4th pixel
    c, s, _ = parts
    g = _kernels.local_frequency_sample(c, s, mask, 2, 4)
    g99 = float(np.quantile(g, 0.99)) if g.size else 0.0
    if g99 > 0:
        w_grad = int(1.4 * np.pi / g99)
        if w_grad % 2 == 0:
            w_grad -= 1
        w = min(w, w_grad)
        if w < 3:                      # fringes too dense to smooth: plain reliability sorting
            w = 1
    return w, density, parts


def unwrap_filtered(psi, mask=None, quality=None, window: int | None = None):
    """Noise-robust unwrapping: smooth in the complex domain, unwrap, make congruent.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    mask : (H, W) bool or None
        True where valid; ``None``: NaN pixels are masked.
    quality : (H, W) array_like of float or None
        Pixel quality (higher = better) that orders the path; ``None``: Herráez reliability of
        the smoothed map.
    window : int or None
        Side of the (odd) smoothing box.  ``None`` chooses it: 1 (no smoothing) when the map has
        fewer than 1e-4 residues per pixel, else 3, 5 or 7 with growing residue density, capped
        so that the phase changes by less than ``1.4 pi`` across the window (a box average of a
        locally linear phase is unbiased while the change across it is below ``2*pi``); when
        even a 3 x 3 box is too wide (gradients above ``1.4 pi / 3`` rad/pixel), no smoothing.

    Returns
    -------
    phi : (H, W) float64, congruent with `psi`, NaN outside the mask.

    Raises
    ------
    ValueError
        As :func:`unwrap_quality`; also for an even or non-positive `window`.

    Notes
    -----
    The smoothing assumes the phase is locally smooth at the scale of the window.  Fields with
    fringes denser than about ``window / 2`` pixels per fringe or many true discontinuities should
    use ``window=1`` (plain reliability sorting) or a reference phase.
    """
    p, m = check_phase_map(psi, mask)
    q = None if quality is None else check_map_like(quality, p.shape, "quality", m)
    p = _principal(p)
    parts = None
    if window is None:
        w, density, parts = _auto_window(p, m)
        log.debug("unwrap_filtered: residue density %.2e -> window %d", density, w)
    else:
        w = int(window)
        if w < 1 or w % 2 == 0 or w != window:
            raise ValueError(f"window must be a positive odd integer, got {window!r}")
    if w == 1:
        return _finish(p, m, _path_follow(p, m, _reliability(p, m, q)))
    ps, _ = smooth_wrapped(p, m, w, parts)
    ps[~m] = 0.0
    n_s = _path_follow(ps, m, _reliability(ps, m, q))
    phi_s = ps + TWO_PI * n_s
    # congruence: keep the data, take the multiple of 2pi from the smoothed estimate
    n = np.rint((phi_s - p) / TWO_PI)
    return _finish(p, m, n)
