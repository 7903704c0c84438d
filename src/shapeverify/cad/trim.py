"""Trimmed parameter domains: which (u, v) of a NURBS surface belong to a face (thesis §7.3).

A trimmed face keeps the part of its surface's parameter rectangle enclosed by its trimming loops:
one outer boundary and any number of holes, each a closed polyline in (u, v).  A point belongs to
the face when a ray from it crosses the loops an odd number of times (the even-odd rule), which
needs no loop orientation and handles holes, and holes in islands, without special cases.

The test is vectorized: :class:`TrimDomain` buckets the loop segments into slabs along v once, and
a numba kernel answers each point by looking only at the segments of its slab.

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

import numpy as np

from . import _trim_kernels

__all__ = ["TrimDomain", "check_loops"]


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
        a = np.concatenate(self.loops)
        b = np.concatenate([np.roll(lp, -1, axis=0) for lp in self.loops])
        self._x0, self._y0 = np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1])
        self._x1, self._y1 = np.ascontiguousarray(b[:, 0]), np.ascontiguousarray(b[:, 1])
        n_seg = a.shape[0]
        if n_bins is None:
            n_bins = int(np.clip(n_seg // 2, 1, 4096))
        elif n_bins < 1:
            raise ValueError(f"n_bins must be >= 1, got {n_bins}")
        self._bins = _trim_kernels.build_bins(self._y0, self._y1, int(n_bins))
        lo, hi = a.min(axis=0), a.max(axis=0)
        self.bounds = ((float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1])))

    @property
    def n_segments(self) -> int:
        return self._x0.shape[0]

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
        vmin, vmax, inv_dv, bin_start, bin_segs = self._bins
        return _trim_kernels.even_odd(u, v, self._x0, self._y0, self._x1, self._y1,
                                      vmin, vmax, inv_dv, bin_start, bin_segs, out)

    def __repr__(self) -> str:
        (u0, u1), (v0, v1) = self.bounds
        return (f"TrimDomain(loops={len(self.loops)}, segments={self.n_segments}, "
                f"u=[{u0:.6g}, {u1:.6g}], v=[{v0:.6g}, {v1:.6g}])")
