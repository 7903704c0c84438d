"""Trimmed parameter domains: which (u, v) of a NURBS surface belong to a face (thesis §7.3).

A trimmed face keeps the part of its surface's parameter rectangle enclosed by its trimming loops:
one outer boundary and any number of holes, each a closed polyline in (u, v).  A point belongs to
the face when a ray from it crosses the loops an odd number of times (the even-odd rule), which
needs no loop orientation and handles holes, and holes in islands, without special cases.

The test is vectorized: :func:`pack_trims` buckets the loop segments of one or many faces into slabs
along v once (a :class:`PackedTrims`), and one numba kernel (``_trim_kernels.inside``) answers each
point by looking only at the segments of its slab.  :class:`TrimDomain` (one face), the exact closest
point and the ray intersection all use it.

Example
-------
>>> import numpy as np
>>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
>>> hole = 0.5 + 0.2 * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
>>> dom = TrimDomain((square, hole))
>>> dom.contains([[0.1, 0.1], [0.5, 0.5], [1.5, 0.5]]).tolist()
[True, False, False]

References
----------
Bergström (2011), thesis §7.3 (trimmed NURBS surfaces).
Haines, "Point in polygon strategies", Graphics Gems IV (1994): the crossing test.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# ``_trim_kernels`` (numba) is imported where it is called: building a model needs no numba.

__all__ = ["TrimDomain", "check_loops", "PackedTrims", "pack_trims", "loop_segments"]

_MAX_BINS = 4096


def check_loops(loops) -> tuple[np.ndarray, ...]:
    """Validate trimming loops; return them as read-only (k, 2) float64 arrays.

    Parameters
    ----------
    loops : sequence of (k, 2) array_like
        Closed polylines in (u, v), the closing segment implied (last vertex != first); k >= 2
        (a 2-vertex loop is a degenerate back-and-forth segment and encloses nothing).

    Raises
    ------
    ValueError
        If there is no loop, a loop is not (k, 2) with k >= 2, or holds non-finite values.
    """
    if isinstance(loops, np.ndarray) and loops.ndim == 2:
        raise ValueError("loops must be a sequence of (k, 2) arrays, got a single array; "
                         "wrap it as (loop,)")
    out = []
    for i, lp in enumerate(loops):
        a = np.ascontiguousarray(lp, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 2:
            raise ValueError(f"loop {i} must have shape (k, 2) with k >= 2, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"loop {i} contains non-finite (u, v) values")
        a.setflags(write=False)
        out.append(a)
    if not out:
        raise ValueError("a trimmed face needs at least one loop (its outer boundary)")
    return tuple(out)


def loop_segments(loops) -> tuple[np.ndarray, np.ndarray]:
    """The segments of closed loops: start points (S, 2) and end points (S, 2), loop by loop."""
    a = np.concatenate(loops)
    b = np.concatenate([np.roll(lp, -1, axis=0) for lp in loops])
    return a, b


class PackedTrims(NamedTuple):
    """The trimming segments of faces ``0 .. F-1`` bucketed into slabs along v, for the numba
    even-odd test (``_trim_kernels.inside(trims, f, u, v)``).  Built by :func:`pack_trims`.

    Attributes
    ----------
    lo, hi : (F,) float64
        v range of each face's segments.
    inv : (F,) float64
        Bins per unit v (0 when all of a face's segments lie at one v).
    bin_off : (F + 1,) int64
        Bins of face f: ``bin_off[f]:bin_off[f+1]``.
    bin_start : (B + 1,) int64
        Entries of bin g: ``bin_start[g]:bin_start[g+1]``.
    bin_xy : (K, 4) float64
        Per entry a copy ``(u0, v0, u1, v1)`` of a segment that crosses the bin's v range (the
        test reads contiguous memory).
    """

    lo: np.ndarray
    hi: np.ndarray
    inv: np.ndarray
    bin_off: np.ndarray
    bin_start: np.ndarray
    bin_xy: np.ndarray

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in self))


def _slabs(y0: np.ndarray, y1: np.ndarray, n_bins: int):
    """Bucket segments with v ranges [min(y0, y1), max(y0, y1)] into ``n_bins`` slabs:
    (lo, hi, inv, bin_start (n_bins + 1,), bin_segs (K,) segment indices)."""
    lo_s = np.minimum(y0, y1)
    hi_s = np.maximum(y0, y1)
    lo = float(lo_s.min())
    hi = float(hi_s.max())
    inv = n_bins / (hi - lo) if hi > lo else 0.0
    b0 = np.clip(((lo_s - lo) * inv).astype(np.int64), 0, n_bins - 1)
    b1 = np.clip(((hi_s - lo) * inv).astype(np.int64), 0, n_bins - 1)
    cnt = b1 - b0 + 1
    seg = np.repeat(np.arange(y0.shape[0], dtype=np.int64), cnt)
    first = np.repeat(np.cumsum(cnt) - cnt, cnt)
    b = np.repeat(b0, cnt) + (np.arange(seg.shape[0], dtype=np.int64) - first)
    order = np.argsort(b, kind="stable")
    start = np.zeros(n_bins + 1, dtype=np.int64)
    np.cumsum(np.bincount(b, minlength=n_bins), out=start[1:])
    return lo, hi, inv, start, seg[order]


def pack_trims(segments, n_bins=None) -> PackedTrims:
    """Pack the trimming segments of faces for the even-odd test.

    Parameters
    ----------
    segments : sequence of ((S, 2), (S, 2)) float64
        Per face, the start and end points in (u, v) of its loop segments (:func:`loop_segments`),
        S >= 1.
    n_bins : None or sequence of int >= 1
        Slabs per face; default ``clip(S // 2, 1, 4096)``.  The answers do not depend on it
        (only the time per test does).

    Returns
    -------
    PackedTrims
    """
    lo, hi, inv, bin_off, starts, xy = [], [], [], [0], [], []
    n_entries = 0
    for f, (a, b) in enumerate(segments):
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        nb = int(np.clip(len(a) // 2, 1, _MAX_BINS)) if n_bins is None else int(n_bins[f])
        if nb < 1:
            raise ValueError(f"n_bins must be >= 1, got {nb} for face {f}")
        lo_f, hi_f, inv_f, st, sg = _slabs(np.ascontiguousarray(a[:, 1]), np.ascontiguousarray(b[:, 1]), nb)
        lo.append(lo_f)
        hi.append(hi_f)
        inv.append(inv_f)
        bin_off.append(bin_off[-1] + nb)
        starts.append(st[:-1] + n_entries)
        n_entries += sg.shape[0]
        xy.append(np.column_stack([a[sg, 0], a[sg, 1], b[sg, 0], b[sg, 1]]))
    if not xy:
        raise ValueError("pack_trims needs the segments of at least one face")
    f64 = np.float64
    return PackedTrims(np.array(lo, dtype=f64), np.array(hi, dtype=f64), np.array(inv, dtype=f64),
                       np.array(bin_off, dtype=np.int64),
                       np.append(np.concatenate(starts), n_entries).astype(np.int64),
                       np.ascontiguousarray(np.concatenate(xy), dtype=f64))


class TrimDomain:
    """The trimmed part of a parameter plane, bounded by closed polylines.

    Parameters
    ----------
    loops : sequence of (k, 2) array_like
        Outer boundary first, then holes (the order does not matter for :meth:`contains`).
    n_bins : int, optional
        Number of slabs along v; default about one per two segments, at most 4096.

    Attributes
    ----------
    loops : tuple of (k, 2) float64
    bounds : ((u0, u1), (v0, v1))
        Bounding box of the loops.
    """

    def __init__(self, loops, n_bins: int | None = None):
        self.loops = check_loops(loops)
        a, b = loop_segments(self.loops)
        self._n_segments = a.shape[0]
        if n_bins is not None and n_bins < 1:
            raise ValueError(f"n_bins must be >= 1, got {n_bins}")
        self._trims = pack_trims([(a, b)], None if n_bins is None else [n_bins])
        lo, hi = a.min(axis=0), a.max(axis=0)
        self.bounds = ((float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1])))

    @property
    def n_segments(self) -> int:
        return self._n_segments

    def contains(self, uv) -> np.ndarray:
        """Whether parameter points lie inside the trimmed domain (even-odd rule over all loops).

        Parameters
        ----------
        uv : (N, 2) or (2,) array_like

        Returns
        -------
        (N,) bool
            Points exactly on a loop may go either way.

        Raises
        ------
        ValueError
            If ``uv`` does not have shape (N, 2) or (2,), or holds NaN or inf.
        """
        p = np.asarray(uv, dtype=np.float64)
        if p.ndim == 1 and p.shape[0] == 2:
            p = p[None, :]
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"uv must have shape (N, 2), got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError("uv contains non-finite values")
        u = np.ascontiguousarray(p[:, 0])
        v = np.ascontiguousarray(p[:, 1])
        out = np.empty(p.shape[0], dtype=np.bool_)
        from . import _trim_kernels

        return _trim_kernels.contains(self._trims, 0, u, v, out)

    def __repr__(self) -> str:
        (u0, u1), (v0, v1) = self.bounds
        return (f"TrimDomain(loops={len(self.loops)}, segments={self.n_segments}, "
                f"u=[{u0:.6g}, {u1:.6g}], v=[{v0:.6g}, {v1:.6g}])")
