"""CAD-regularised unwrapping as a minimum-norm problem: a sum of norms solved by IRLS.

The thesis (Ch. 4.2, Paper V) describes its CAD-regularised unwrapping as "a type of minimum-norm
method, since we are minimizing an objective function of a sum of norms".  This module states
that objective directly,

    E(phi) = sum_edges  w_e |(D phi)_e - g_e|^p   +   lam * sum_pixels |phi_i - r_i|^q,

with ``g`` the wrapped phase gradients of the data (Ch. 4.2: "the phase gradient ... the wrapped
phase difference of adjacent pixels"), ``D`` the forward differences between 4-neighbours, ``r``
the phase predicted from the CAD model and ``w`` optional edge weights.  The data term alone is the
classical minimum Lp-norm unwrapping (it cannot see a step of more than ``pi``: the wrapped
gradient across it is off by ``2*pi``); the CAD term pulls every region to the level the model
predicts, so a step costs ``|2*pi|^p`` per edge along it in the data term but saves
``lam * |2*pi|^q`` per pixel of the region in the CAD term, and large regions are placed on the
predicted fringe.  With ``p, q <= 1`` both terms are robust: a few wrong gradients (noise, true
steps) and a few wrong predictions (misplaced model edges, local defects) do not spread.

The minimum is found by iteratively reweighted least squares (Ghiglia & Pritt 1998, Ch. 5.5):
each step solves ``(D^T U D + lam V) phi = D^T U g + lam V r`` with ``U = w / max(|res|, eps)^(2-p)``
and ``V = 1 / max(|phi - r|, eps)^(2-q)`` (sparse LU, or conjugate gradients for large maps), and the result is
made congruent with the data (``phi = psi + 2*pi*round((phi - psi) / (2*pi))``).

:func:`shapeverify.phase.unwrap_with_reference` (the difference method of ``regularised.py``)
stays the default; ``benchmarks/bench_phase.py`` compares the two.

References
----------
Bergström (2011), thesis Ch. 4.2 and Paper V; D. C. Ghiglia, M. D. Pritt, *Two-Dimensional Phase
Unwrapping*, Wiley 1998, Ch. 5.5 (minimum Lp-norm, IRLS).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import cg, splu

from .wrap import TWO_PI, check_map_like, check_phase_map, wrap

log = logging.getLogger(__name__)

__all__ = ["unwrap_sum_of_norms", "SumOfNormsUnwrap"]

#: up to this many valid pixels each IRLS step is solved directly (sparse LU), beyond by
#: Jacobi-preconditioned conjugate gradients
_DIRECT_MAX = 400_000


@dataclass(frozen=True, repr=False)
class SumOfNormsUnwrap:
    """Result of :func:`unwrap_sum_of_norms`.

    Attributes
    ----------
    phase : (H, W) float64
        Unwrapped phase, congruent with the data, NaN outside the mask.
    iterations : int
        IRLS steps taken.
    converged : bool
        No pixel changed its ``2*pi`` multiple in the last step (before `max_iter`).
    objective : float
        ``E(phi)`` of the last continuous iterate (before rounding).
    """

    phase: np.ndarray
    iterations: int
    converged: bool
    objective: float

    def __repr__(self):
        return (f"SumOfNormsUnwrap(shape={self.phase.shape}, iterations={self.iterations}, "
                f"converged={self.converged}, objective={self.objective:.4g})")


def _difference_operator(m):
    """Sparse forward differences over valid edges between valid pixels; pixel index map."""
    H, W = m.shape
    idx = -np.ones((H, W), np.int64)
    idx[m] = np.arange(int(m.sum()))
    ah, bh = idx[:, :-1], idx[:, 1:]
    av, bv = idx[:-1, :], idx[1:, :]
    a = np.concatenate([ah.ravel(), av.ravel()])
    b = np.concatenate([bh.ravel(), bv.ravel()])
    ok = (a >= 0) & (b >= 0)
    a, b = a[ok], b[ok]
    k = a.size
    rows = np.repeat(np.arange(k), 2)
    cols = np.stack([a, b], axis=1).ravel()
    vals = np.tile([-1.0, 1.0], k)
    D = sp.csr_matrix((vals, (rows, cols)), shape=(k, int(m.sum())))
    return D, ok, idx


def unwrap_sum_of_norms(psi, reference, mask=None, weights=None, p: float = 1.0, q: float = 1.0,
                        lam: float = 0.05, eps: float = 1e-2, max_iter: int = 40,
                        cg_tol: float = 1e-6) -> SumOfNormsUnwrap:
    """Unwrap with a CAD prediction by minimising a sum of norms (data gradients + CAD term).

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    reference : (H, W) array_like of float
        Predicted unwrapped phase from the CAD model (finite on valid pixels).
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels of `psi` are masked).
    weights : (H, W) array_like of float >= 0, or None
        Pixel quality; an edge gets the smaller weight of its two pixels (scaled to max 1).
    p, q : float in (0, 2]
        Norms of the data term and of the CAD term (1 and 1: both robust and convex).
    lam : float > 0
        Weight of the CAD term relative to the data term.
    eps : float > 0
        IRLS smoothing: residuals below `eps` are weighted as `eps`.
    max_iter : int >= 1
        IRLS steps at most.
    cg_tol : float
        Relative tolerance of each conjugate-gradient solve (maps of more than 400,000 valid
        pixels; smaller ones are solved directly by sparse LU).

    Returns
    -------
    SumOfNormsUnwrap

    Raises
    ------
    ValueError
        Bad `psi`/`mask` (as :func:`shapeverify.phase.unwrap`), reference or weights of the wrong
        shape or not finite on valid pixels, negative weights, `p`/`q` outside (0, 2], `lam` or
        `eps` not positive, `max_iter` < 1.

    Examples
    --------
    >>> y, x = np.mgrid[0:40, 0:50]
    >>> true = 0.1 * x + np.where(x > 25, 7.5, 0.0)             # a 2.4 pi step
    >>> res = unwrap_sum_of_norms(wrap(true), true + 0.3 * np.cos(y / 9.0))
    >>> bool(np.allclose(res.phase, true))
    True
    """
    ps, m = check_phase_map(psi, mask)
    ref = check_map_like(reference, ps.shape, "reference", m)
    for name, v in (("p", p), ("q", q)):
        if not 0.0 < v <= 2.0:
            raise ValueError(f"{name} must be in (0, 2], got {v!r}")
    if not lam > 0:
        raise ValueError(f"lam (weight of the CAD term) must be > 0, got {lam!r}")
    if not eps > 0:
        raise ValueError(f"eps must be > 0, got {eps!r}")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1, got {max_iter!r}")
    if weights is None:
        pw = np.ones(ps.shape)
    else:
        pw = check_map_like(weights, ps.shape, "weights", m)
        if (pw[m] < 0).any():
            raise ValueError("weights must be >= 0")
        mx = float(pw[m].max())
        if mx <= 0:
            raise ValueError("weights are zero on every valid pixel")
        pw = pw / mx
    D, ok, _ = _difference_operator(m)
    g_all = np.concatenate([wrap(np.diff(ps, axis=1)).ravel(), wrap(np.diff(ps, axis=0)).ravel()])
    w_all = np.concatenate([np.minimum(pw[:, 1:], pw[:, :-1]).ravel(),
                            np.minimum(pw[1:, :], pw[:-1, :]).ravel()])
    g = g_all[ok]
    w = w_all[ok]
    r = ref[m]
    x = r + wrap(ps[m] - r)                       # start: the pixel-wise nearest congruent value
    n_old = np.rint((x - ps[m]) / TWO_PI)
    DT = D.T.tocsr()
    converged = False
    it = 0
    for it in range(1, int(max_iter) + 1):
        res = D @ x - g
        u = w / np.maximum(np.abs(res), eps) ** (2.0 - p)
        v = lam / np.maximum(np.abs(x - r), eps) ** (2.0 - q)
        A = (DT @ sp.diags(u) @ D + sp.diags(v)).tocsr()
        rhs = DT @ (u * g) + v * r
        if x.size <= _DIRECT_MAX:
            x = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(rhs)
        else:
            x, info = cg(A, rhs, x0=x, rtol=cg_tol, maxiter=1000, M=sp.diags(1.0 / A.diagonal()))
            if info > 0:
                log.debug("sum_of_norms: CG stopped at maxiter in step %d", it)
        n_new = np.rint((x - ps[m]) / TWO_PI)
        changed = int(np.count_nonzero(n_new != n_old))
        log.debug("sum_of_norms: step %d, %d pixels changed", it, changed)
        n_old = n_new
        if changed == 0 and it > 1:
            converged = True
            break
    res = D @ x - g
    obj = float(np.sum(w * np.abs(res) ** p) + lam * np.sum(np.abs(x - r) ** q))
    phi = np.full(ps.shape, np.nan)
    phi[m] = ps[m] + TWO_PI * n_old
    return SumOfNormsUnwrap(phase=phi, iterations=it, converged=converged, objective=obj)
