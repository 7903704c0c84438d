"""numba kernels of the point-in-trimmed-domain test (private; trust their input).

The one even-odd test of the project: :class:`~shapeverify.cad.trim.TrimDomain` (one face), the
exact closest point (:mod:`shapeverify.nearest`) and the ray intersection
(:mod:`shapeverify.camera`) all call :func:`inside` on a
:class:`~shapeverify.cad.trim.PackedTrims`.  The segments of a face's trimming loops are
bucketed into horizontal slabs (bins along v); a point casts a ray towards +u and only the
segments of its own slab can cross that ray, so the cost per point is the number of segments in
one slab, not in the whole face.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True, inline="always")
def inside(trims, f, u, v):
    """Whether (u, v) lies inside the trimming loops of face ``f`` (even-odd rule).

    ``trims`` is a :class:`~shapeverify.cad.trim.PackedTrims`.  A segment counts as crossed
    when v lies in its half-open v range [min, max) and the crossing lies at u' > u (the
    PNPOLY rule), so a ray through a shared vertex is counted once.  Points outside the face's
    v range (and NaN) are outside.
    """
    if not (v >= trims.lo[f] and v <= trims.hi[f]):
        return False
    nb = trims.bin_off[f + 1] - trims.bin_off[f]
    b = min(max(int((v - trims.lo[f]) * trims.inv[f]), 0), nb - 1)
    g = trims.bin_off[f] + b
    xy = trims.bin_xy
    res = False
    for k in range(trims.bin_start[g], trims.bin_start[g + 1]):
        ya = xy[k, 1]
        yb = xy[k, 3]
        if (ya > v) != (yb > v):
            xc = xy[k, 0] + (v - ya) * (xy[k, 2] - xy[k, 0]) / (yb - ya)
            if u < xc:
                res = not res
    return res


@njit(cache=True, nogil=True)
def contains(trims, f, u, v, out):
    """:func:`inside` for every point: u, v (N,) float64; out (N,) bool, written in place."""
    for k in range(u.shape[0]):
        out[k] = inside(trims, f, u[k], v[k])
    return out
