"""numba kernel for the point-in-trimmed-domain test (private; trusts its input).

The segments of all trimming loops of a face are bucketed into horizontal slabs (bins along v).
A point casts a ray towards +u; only the segments of its own slab can cross that ray, so the cost
per point is the number of segments in one slab, not in the whole face.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def even_odd(u, v, x0, y0, x1, y1, vmin, vmax, inv_dv, bin_start, bin_segs, out):
    """Even-odd (crossing number) test of points against a set of segments.

    u, v : (N,) float64          -- query points
    x0, y0, x1, y1 : (S,) float64 -- segment end points (u, v)
    vmin, vmax : float            -- v range covered by the bins
    inv_dv : float                -- bins per unit v
    bin_start : (B + 1,) int64    -- segments of bin b are bin_segs[bin_start[b]:bin_start[b+1]]
    bin_segs : (K,) int64
    out : (N,) bool, written in place

    A segment counts as crossed when v lies in its half-open v range [min, max) and the crossing
    lies at u' > u (the PNPOLY rule), so a ray through a shared vertex is counted once.
    """
    nb = bin_start.shape[0] - 1
    for k in range(u.shape[0]):
        uk = u[k]
        vk = v[k]
        if not (vk >= vmin and vk <= vmax):
            out[k] = False
            continue
        b = int((vk - vmin) * inv_dv)
        if b >= nb:
            b = nb - 1
        if b < 0:
            b = 0
        inside = False
        for m in range(bin_start[b], bin_start[b + 1]):
            s = bin_segs[m]
            ya = y0[s]
            yb = y1[s]
            if (ya > vk) != (yb > vk):
                xa = x0[s]
                xc = xa + (vk - ya) * (x1[s] - xa) / (yb - ya)
                if uk < xc:
                    inside = not inside
        out[k] = inside
    return out


def build_bins(y0: np.ndarray, y1: np.ndarray, n_bins: int):
    """Bucket segments with v ranges [min(y0, y1), max(y0, y1)] into ``n_bins`` slabs.

    Returns ``(vmin, vmax, inv_dv, bin_start, bin_segs)`` for :func:`even_odd`.
    """
    lo = np.minimum(y0, y1)
    hi = np.maximum(y0, y1)
    vmin = float(lo.min())
    vmax = float(hi.max())
    span = vmax - vmin
    inv_dv = n_bins / span if span > 0 else 0.0
    b0 = np.clip(((lo - vmin) * inv_dv).astype(np.int64), 0, n_bins - 1)
    b1 = np.clip(((hi - vmin) * inv_dv).astype(np.int64), 0, n_bins - 1)
    counts = b1 - b0 + 1
    seg = np.repeat(np.arange(y0.shape[0], dtype=np.int64), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    bins = np.repeat(b0, counts) + (np.arange(seg.shape[0], dtype=np.int64) - first)
    order = np.argsort(bins, kind="stable")
    bin_segs = np.ascontiguousarray(seg[order])
    bin_start = np.zeros(n_bins + 1, dtype=np.int64)
    np.cumsum(np.bincount(bins, minlength=n_bins), out=bin_start[1:])
    return vmin, vmax, inv_dv, bin_start, bin_segs
