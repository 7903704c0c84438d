"""Minimum-norm unwrapping: least squares by DCT, weighted LS by PCG, minimum Lp-norm by IRLS.

The unknown phase ``phi`` minimises a sum of norms of the differences between its gradient and
the wrapped gradient of the data (thesis Ch. 4.2),

    sum_x  w_x |phi[i,j+1] - phi[i,j] - W(psi[i,j+1] - psi[i,j])|^p  +  (same along y).

* ``p = 2``, unit weights: a discrete Poisson equation with Neumann boundaries, solved directly
  by the 2-D DCT (Ghiglia & Romero 1994) -- :func:`unwrap_ls`.
* ``p = 2`` with weights (a quality map, or 0/1 for a mask): the weighted normal equations solved
  by conjugate gradients preconditioned with the DCT solver (Ghiglia & Romero 1994,
  Ghiglia & Pritt 1998 Ch. 5.3) -- :func:`unwrap_wls`.
* ``p < 2``: iteratively reweighted least squares, each step a weighted LS problem with weights
  ``eps / (|r|^(2-p) + eps)`` from the current residual ``r`` (Ghiglia & Pritt 1998 Ch. 5.5) --
  :func:`unwrap_lp`.  ``p = 0`` (the default) concentrates the disagreement with the wrapped
  gradients on as few edges as possible, which is what a discontinuity needs.

The LS solution is smooth, not congruent: it underestimates slopes near residues.  By default
the result is made congruent (``phi + W(psi - phi)``, Ghiglia & Pritt Ch. 5.2), i.e. each pixel
keeps its measured value and only the multiple of ``2*pi`` comes from the minimum-norm solution.

References
----------
D. C. Ghiglia, L. A. Romero, "Robust two-dimensional weighted and unweighted phase unwrapping
that uses fast transforms and iterative methods", JOSA A 11 (1994) 107-117.
D. C. Ghiglia, M. D. Pritt, *Two-Dimensional Phase Unwrapping*, Wiley 1998, Ch. 5.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy import fft as sfft

from . import _kernels
from .wrap import TWO_PI, check_map_like, check_phase_map, wrap

log = logging.getLogger(__name__)

__all__ = ["unwrap_ls", "unwrap_wls", "unwrap_lp", "solve_poisson_dct"]


def solve_poisson_dct(rho):
    """Solve the discrete Poisson equation with Neumann boundaries by the DCT.

    Finds ``phi`` with ``L phi = rho`` where ``L`` is the 5-point Laplacian whose terms beyond the
    border are absent; the solution has zero mean (the constant is free).

    Parameters
    ----------
    rho : (H, W) float64

    Returns
    -------
    phi : (H, W) float64

    References
    ----------
    Ghiglia & Romero (1994), eq. (10); Ghiglia & Pritt (1998), Ch. 5.3.
    """
    H, W = rho.shape
    r = sfft.dctn(rho, type=2, norm="ortho")
    ci = 2.0 * np.cos(np.pi * np.arange(H) / H)[:, None]
    cj = 2.0 * np.cos(np.pi * np.arange(W) / W)[None, :]
    den = ci + cj - 4.0
    den[0, 0] = 1.0
    r /= den
    r[0, 0] = 0.0
    return sfft.idctn(r, type=2, norm="ortho")


def _wrapped_gradients(psi, mask):
    gx = wrap(np.diff(psi, axis=1))
    gy = wrap(np.diff(psi, axis=0))
    gx[~(mask[:, 1:] & mask[:, :-1])] = 0.0
    gy[~(mask[1:, :] & mask[:-1, :])] = 0.0
    return gx, gy


def _edge_weights(pix_w):
    """Edge weights from pixel weights: min of the squared pixel weights (Ghiglia & Pritt 5.3)."""
    w2 = pix_w * pix_w
    return np.minimum(w2[:, 1:], w2[:, :-1]), np.minimum(w2[1:, :], w2[:-1, :])


def _pcg(gx, gy, wx, wy, x0=None, tol=1e-6, max_iter=200):
    """Solve the weighted LS normal equations ``A phi = b`` by DCT-preconditioned CG."""
    H = wy.shape[0] + 1
    W = wx.shape[1] + 1
    b = _kernels.weighted_divergence(gx, gy, wx, wy, np.empty((H, W)))
    # K = -A is symmetric positive semidefinite; the preconditioner is (-L)^-1
    f = -b
    x = np.zeros((H, W)) if x0 is None else x0.copy()
    Ax = np.empty((H, W))
    r = f + _kernels.weighted_laplacian(x, wx, wy, Ax)
    fnorm = np.sqrt(_kernels.fdot(f, f))
    if fnorm == 0.0:
        return x, 0, True
    z = -solve_poisson_dct(r)
    p = z.copy()
    rz = _kernels.fdot(r, z)
    for k in range(1, max_iter + 1):
        Kp = -_kernels.weighted_laplacian(p, wx, wy, Ax)
        pKp = _kernels.fdot(p, Kp)
        if pKp <= 0.0:
            return x, k, np.sqrt(_kernels.fdot(r, r)) <= tol * fnorm
        alpha = rz / pKp
        x += alpha * p
        r -= alpha * Kp
        if np.sqrt(_kernels.fdot(r, r)) <= tol * fnorm:
            return x, k, True
        z = -solve_poisson_dct(r)
        rz_new = _kernels.fdot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x, max_iter, False


def _finish(phi, psi, mask, congruent):
    if congruent:
        phi = psi + TWO_PI * np.rint((phi - psi) / TWO_PI)
    else:
        phi = phi - np.mean(phi[mask]) + np.mean(psi[mask])
    phi = np.array(phi, dtype=np.float64)
    phi[~mask] = np.nan
    return phi


def _pixel_weights(psi_shape, mask, weights):
    if weights is None:
        return mask.astype(np.float64)
    w = check_map_like(weights, psi_shape, "weights", mask)
    if (w[mask] < 0).any():
        raise ValueError("weights must be >= 0 (0 = ignore the pixel, larger = more trusted)")
    wmax = float(w[mask].max())
    if wmax <= 0:
        raise ValueError("weights are zero on every valid pixel")
    return np.where(mask, w / wmax, 0.0)


def unwrap_ls(psi, mask=None, congruent: bool = True):
    """Unweighted least-squares unwrapping by the DCT (Ghiglia & Romero 1994).

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels masked).  With masked pixels the problem is a
        weighted one with 0/1 weights and is solved by :func:`unwrap_wls`.
    congruent : bool
        Make the result congruent with `psi` (default).  ``False`` returns the smooth LS
        solution, shifted so that its mean equals the mean of `psi`.

    Returns
    -------
    phi : (H, W) float64, NaN outside the mask.

    Raises
    ------
    ValueError
        As :func:`shapeverify.phase.unwrap`.

    Examples
    --------
    >>> y, x = np.mgrid[0:40, 0:50]
    >>> true = 0.3 * x - 0.2 * y + 0.01 * x * y
    >>> phi = unwrap_ls(wrap(true))
    >>> bool(np.allclose(phi - phi[0, 0], true - true[0, 0]))
    True
    """
    p, m = check_phase_map(psi, mask)
    if not m.all():
        return _unwrap_wls(p, m, m.astype(np.float64), congruent)
    gx, gy = _wrapped_gradients(p, m)
    rho = _kernels.weighted_divergence(gx, gy, np.ones_like(gx), np.ones_like(gy), np.empty(p.shape))
    return _finish(solve_poisson_dct(rho), p, m, congruent)


def _unwrap_wls(p, m, pix_w, congruent, tol=1e-6, max_iter=200):
    gx, gy = _wrapped_gradients(p, m)
    wx, wy = _edge_weights(pix_w)
    phi, it, ok = _pcg(gx, gy, wx, wy, tol=tol, max_iter=max_iter)
    if not ok:
        log.warning("weighted LS: PCG did not reach tol=%g in %d iterations", tol, it)
    return _finish(phi, p, m, congruent)


def unwrap_wls(psi, mask=None, weights=None, congruent: bool = True, tol: float = 1e-6,
               max_iter: int = 200):
    """Weighted least-squares unwrapping by DCT-preconditioned conjugate gradients.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels masked); masked pixels get weight 0.
    weights : (H, W) array_like of float >= 0, or None
        Pixel weights (a quality map: modulation, coherence, ...), scaled to a maximum of 1.
        An edge gets the smaller squared weight of its two pixels.  ``None``: the mask (0/1).
    congruent : bool
        Make the result congruent with `psi` (default).
    tol, max_iter
        PCG stops at ``||r|| <= tol * ||b||`` or after `max_iter` iterations (then a warning is
        logged; the best iterate is still returned).

    Returns
    -------
    phi : (H, W) float64, NaN outside the mask.

    Raises
    ------
    ValueError
        Bad `psi`/`mask` as :func:`shapeverify.phase.unwrap`; weights of the wrong shape,
        negative, non-finite on valid pixels, or all zero.

    References
    ----------
    Ghiglia & Romero (1994); Ghiglia & Pritt (1998), Ch. 5.3 (algorithm PCG).
    """
    p, m = check_phase_map(psi, mask)
    return _unwrap_wls(p, m, _pixel_weights(p.shape, m, weights), congruent, tol, max_iter)


def unwrap_lp(psi, mask=None, weights=None, p: float = 0.0, congruent: bool = True,
              eps: float = 0.01, max_outer: int = 50, tol: float = 1e-3, max_iter: int = 100):
    """Minimum Lp-norm unwrapping by iteratively reweighted least squares.

    Each outer step solves a weighted LS problem (:func:`unwrap_wls`) with edge weights
    ``w_edge * eps / (|r|^(2-p) + eps)``, where ``r`` is the difference between the current
    solution's gradient and the wrapped data gradient on that edge.  It stops when the
    congruent solution no longer changes (same multiple of ``2*pi`` at every pixel) or after
    `max_outer` steps.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    mask, weights
        As :func:`unwrap_wls`.
    p : float in [0, 2)
        The norm.  0 (default) is the most robust to discontinuities (Ghiglia & Pritt
        recommend it), 1 is the L1 norm.
    congruent : bool
        Make the result congruent with `psi` (default).
    eps : float > 0
        Regularisation of the reweighting (residuals well below ``eps**(1/(2-p))`` count as 0).
    max_outer, tol, max_iter
        Outer iterations; PCG tolerance and iterations of each inner solve.

    Returns
    -------
    phi : (H, W) float64, NaN outside the mask.

    Raises
    ------
    ValueError
        As :func:`unwrap_wls`; also `p` outside [0, 2), `eps` <= 0 or `max_outer` < 1.

    References
    ----------
    Ghiglia & Pritt (1998), Ch. 5.5 (minimum Lp-norm, algorithm LPNORM).
    """
    if not 0.0 <= p < 2.0:
        raise ValueError(f"p must be in [0, 2) (use unwrap_wls for p = 2), got {p!r}")
    if not eps > 0:
        raise ValueError(f"eps must be > 0, got {eps!r}")
    if int(max_outer) < 1:
        raise ValueError(f"max_outer must be >= 1, got {max_outer!r}")
    ps, m = check_phase_map(psi, mask)
    pix_w = _pixel_weights(ps.shape, m, weights)
    gx, gy = _wrapped_gradients(ps, m)
    wx0, wy0 = _edge_weights(pix_w)
    phi, _, _ = _pcg(gx, gy, wx0, wy0, tol=tol, max_iter=max_iter)
    n_old = np.rint((phi - ps) / TWO_PI)
    settled = False
    for k in range(max_outer):
        rx = np.diff(phi, axis=1) - gx
        ry = np.diff(phi, axis=0) - gy
        ux = eps / (np.abs(rx) ** (2.0 - p) + eps)
        uy = eps / (np.abs(ry) ** (2.0 - p) + eps)
        phi, _, _ = _pcg(gx, gy, wx0 * ux, wy0 * uy, x0=phi, tol=tol, max_iter=max_iter)
        n_new = np.rint((phi - ps) / TWO_PI)
        changed = int(np.count_nonzero((n_new != n_old) & m))
        log.debug("unwrap_lp: outer %d, %d pixels changed", k, changed)
        # a global shift of all pixels by the same multiple is no change
        if changed == 0 or np.ptp((n_new - n_old)[m]) == 0:
            n_old = n_new
            settled = True
            break
        n_old = n_new
    if not settled:
        log.warning("unwrap_lp: %d pixels still changed after max_outer=%d reweightings",
                    changed, max_outer)
    return _finish(phi if not congruent else ps + TWO_PI * n_old, ps, m, congruent)
