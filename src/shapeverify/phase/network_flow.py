"""Residue-aware unwrapping: minimum-cost-flow L1 unwrapping (Costantini 1998).

Path following decides the ``2*pi`` multiple of every pixel from the order in which it merges
regions; where a true discontinuity of more than ``pi`` crosses part of the field, a merge across
it puts a whole region on the wrong fringe.  The network-flow formulation instead asks for the
integer corrections ``k`` of the wrapped gradients with the smallest total (weighted) cost that
make the gradient field curl-free, i.e. cancel every residue: the residues are the supplies of a
flow network on the dual grid (plus a ground node outside the border), the corrections are the
flows, and the minimum-cost flow is found exactly by successive shortest paths
(:mod:`shapeverify.phase._flow`).  The corrected gradients are then integrated
(path-independently).

The costs decide where the cuts go.  Uniform costs give the shortest cuts (the classical L1
solution); here a correction of ``+-1`` on an edge costs ``pi +- d``, where ``d`` is the edge's
wrapped gradient minus the local mean gradient (the log-likelihood under Gaussian gradient noise).
Across a fault whose step ``s`` exceeds ``pi`` the wrapped gradient is ``s - 2*pi`` against a
smooth neighbourhood, so cutting along the fault costs ``2*pi - s`` per edge instead of ``pi``:
the cut follows the fault to the border rather than taking the shortest way out.

References
----------
M. Costantini, "A novel phase unwrapping method based on network programming", IEEE Trans.
Geosci. Remote Sens. 36 (1998) 813-821.
C. W. Chen, H. A. Zebker, "Network approaches to two-dimensional phase unwrapping", JOSA A 17
(2000) 401-414 (statistical costs).
R. K. Ahuja, T. L. Magnanti, J. B. Orlin, *Network Flows*, Prentice Hall 1993, Ch. 9.
"""

from __future__ import annotations

import logging

import numpy as np

from . import _flow, _kernels
from .path_following import _auto_window, _principal, smooth_wrapped
from .wrap import TWO_PI, check_map_like, check_phase_map

log = logging.getLogger(__name__)

__all__ = ["unwrap_mcf"]


def _integrate(jumps, mask, H, W):
    """Integer field n from curl-free edge jumps over the valid pixels (any spanning order)."""
    valid = _kernels.edge_costs(mask.astype(np.float64), mask) >= 0
    order = np.flatnonzero(valid).astype(np.int64)
    return _kernels.merge_edges(jumps, order, H, W).reshape(H, W)


def unwrap_mcf(psi, mask=None, quality=None, window: int | None = None, beta: float = 1e-3,
               cost: str = "step", pixel_weight: float = 0.1, corners: bool = True):
    """Minimum-cost-flow (network L1) unwrapping, residue-aware (Costantini 1998).

    Steps: (1) the wrapped phase is smoothed in the complex domain as in
    :func:`~shapeverify.phase.unwrap_filtered` (a ``window`` box; none for residue-free data),
    which removes almost all noise residues but keeps the residues of true discontinuities;
    (2) every edge gets a cost for a ``+-2*pi`` correction from the step that two adjacent boxes
    of the raw data see across it against the local trend (:func:`shapeverify.phase._flow.step_anomaly`;
    a log-likelihood ratio under Gaussian noise plus a discontinuity term of weight `beta`,
    with the noise level estimated from the data): small where the phase jumps (a fault),
    about ``-log(beta)`` where it is smooth, plus `pixel_weight` times the same from
    single-pixel steps, which puts the cut on the right pixel edge; (3) the minimum-cost flow on
    the dual grid cancels the residues of the smoothed map (exact successive shortest paths);
    (4) the corrected gradients are integrated and the data made congruent
    (``phi = psi + 2*pi*round((phi_s - psi) / (2*pi))``).

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians.
    mask : (H, W) bool or None
        True where valid (``None``: NaN pixels masked).  Cuts cross masked pixels for free.
    quality : (H, W) array_like of float >= 0, or None
        Pixel weights (e.g. modulation): an edge's costs are scaled by the smaller weight of its
        two pixels (scaled to max 1), so cuts prefer poor pixels.  ``None``: all 1.
    window : odd int or None
        Smoothing box (``None``: chosen from the residue density as in ``unwrap_filtered``).
    beta : float in (0, 1)
        Weight of the discontinuity term of the cost model (smaller = cuts avoid smooth areas
        more strongly).
    pixel_weight : float >= 0
        Weight of a second cost term from single-pixel steps (``b = 0``), which places the cut
        on the exact pixel edge where the data allow it (0 = off).
    corners : bool
        Lower the cost of the corner edges of a staircase cut along a slanted fault to that of
        the cut (:func:`shapeverify.phase._flow.corner_relief`).
    cost : {"step", "uniform"}
        ``"uniform"``: classical unit costs (shortest cuts), for comparison.

    Returns
    -------
    phi : (H, W) float64
        Unwrapped phase, congruent with `psi`, NaN outside the mask (one arbitrary ``2*pi*k``
        offset per 4-connected region of the mask).

    Notes
    -----
    Cost: smoothing and costs are O(N); the flow is exact successive shortest paths, cheap for
    the few residues left after smoothing (a fault's residue that must reach the border costs
    one Dijkstra over the image).  On the 1024^2 fault field of ``benchmarks/bench_phase.py``
    it is about as fast as scikit-image's path following.  A fault whose step is close to
    ``2*pi`` is nearly invisible in the wrapped data (the wrapped step is ``s - 2*pi``) and may
    still be cut the short way; steps of any size predicted by a CAD model are handled by
    :func:`shapeverify.phase.unwrap_with_reference`.

    Raises
    ------
    ValueError
        As :func:`shapeverify.phase.unwrap`; negative or all-zero quality; bad window, beta or
        cost.

    References
    ----------
    M. Costantini, IEEE TGRS 36 (1998) 813-821; Chen & Zebker, JOSA A 17 (2000) 401-414.

    Examples
    --------
    >>> from shapeverify.phase import wrap
    >>> y, x = np.mgrid[0:48, 0:64]
    >>> true = 0.01 * (x - 30.0) ** 2 + 0.2 * y
    >>> phi = unwrap_mcf(wrap(true))
    >>> bool(np.allclose(phi - phi[0, 0], true - true[0, 0]))
    True
    """
    p, m = check_phase_map(psi, mask)
    if not 0.0 < beta < 1.0:
        raise ValueError(f"beta must be in (0, 1), got {beta!r}")
    if cost not in ("step", "uniform"):
        raise ValueError(f"cost must be 'step' or 'uniform', got {cost!r}")
    if quality is None:
        wgt = m.astype(np.float64)
    else:
        wgt = check_map_like(quality, p.shape, "quality", m)
        if (wgt[m] < 0).any():
            raise ValueError("quality must be >= 0 for method 'mcf' (it scales the cut costs)")
        mx = float(wgt[m].max())
        if mx <= 0:
            raise ValueError("quality is zero on every valid pixel")
        wgt = np.where(m, wgt / mx, 0.0)
    p = _principal(p)
    H, W = p.shape
    parts = None
    if window is None:
        w, density, parts = _auto_window(p, m)
        log.debug("unwrap_mcf: residue density %.2e -> window %d", density, w)
    else:
        w = int(window)
        if w < 1 or w % 2 == 0 or w != window:
            raise ValueError(f"window must be a positive odd integer, got {window!r}")
    if parts is None:
        parts = _kernels.phasor_parts(p, m)
    c, s, _ = parts
    b = max(w // 2, 1)
    bc = _kernels.box_sum(c, b)
    bs = _kernels.box_sum(s, b)
    if w > 1:
        ps = np.arctan2(bs, bc) if b == w // 2 else smooth_wrapped(p, m, w, parts)[0]
        ps[~m] = 0.0
    else:
        ps = p
    jumps = _kernels.edge_jumps(ps, m)
    q = _flow.loop_charges(jumps, H, W)
    n_res = int(np.count_nonzero(q[:-1]))
    if n_res:
        ew = np.concatenate([np.minimum(wgt[:, 1:], wgt[:, :-1]).ravel(),
                             np.minimum(wgt[1:, :], wgt[:-1, :]).ravel()])
        if cost == "uniform":
            cp = ew + 1e-6
            cm = cp.copy()
        else:
            d1 = _flow.step_anomaly(m, bc, bs, b)
            d0 = _flow.step_anomaly(m, c, s, 0) if pixel_weight > 0 else d1
            cp, cm = _flow.robust_costs(d1, _noise(d1), d0, _noise(d0), float(pixel_weight), ew,
                                        float(np.log(beta)), 1e-6)
            if corners:
                cp, cm = _flow.corner_relief(cp, cm, H, W)
        flow, n_aug, work = _flow.min_cost_flow(q, cp, cm, H, W)
        log.debug("unwrap_mcf: window %d, %d residues, %d unit paths, %d nodes searched",
                  w, n_res, n_aug, work)
        jumps = jumps.astype(np.int32) + flow
        if np.abs(jumps).max() > 127:
            raise RuntimeError("unwrap_mcf: correction out of int8 range")
        jumps = jumps.astype(np.int8)
    n_s = _integrate(jumps, m, H, W)
    if ps is not p:
        n_s = np.rint((ps + TWO_PI * n_s - p) / TWO_PI)
    return _finish(p, m, n_s)


def _noise(d):
    """Robust noise level of the anomalies (MAD of a regular subsample), floored at 0.02 rad."""
    v = d[:: max(1, d.size // 200_000)]
    v = np.abs(v[np.isfinite(v)])
    return max(1.4826 * float(np.median(v)) if v.size else 0.0, 0.02)


def _finish(p, m, n):
    phi = p + TWO_PI * n
    phi[~m] = np.nan
    return phi
