"""A third :class:`shapeverify.nearest.protocol.ClosestPoints`: scipy's cKDTree over a prepared
model's own model points, and the same tangent-patch projection as the DVG tree's fast mode
(:func:`shapeverify.nearest._kernels._project_one`, written again here in numpy): the nearest
model point by an independent search, its patch (normal, tangent_u, half extents), the foot
clamped to the patch, the distance ``(q - p) . n`` inside it, else ``|q - foot|`` with that
sign.  ``exact=True`` is answered the same way (this structure has no refinement).

Used by ``tests/test_closest_points_contract.py`` so that registration and inspection are shown
to work through the protocol alone.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from shapeverify.nearest import Closest


class KDTreeClosest:
    """ClosestPoints over the model points of ``prep`` (a Prepared model)."""

    def __init__(self, prep):
        mp = prep.points
        self.points = mp
        self.n_points = int(mp.points.shape[0])
        self.spacing = float(prep.spacing)
        self.reach = float(prep.reach)
        self.model = prep.model
        self.fixture = None
        self._kd = cKDTree(np.asarray(mp.points, np.float64))
        n = np.asarray(mp.normals, np.float64)
        u = np.asarray(mp.tangent_u, np.float64)
        u = u - np.sum(u * n, axis=1)[:, None] * n        # as the kernel: u off the plane removed
        self._n, self._u, self._v = n, u, np.cross(n, u)
        self._h = np.asarray(mp.half_extent, np.float64)

    def closest(self, points, exact: bool = False) -> Closest:
        q = np.asarray(points, np.float64)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != 3 or not np.isfinite(q).all():
            raise ValueError(f"points must be finite (N, 3), got shape {q.shape}")
        _, j = self._kd.query(q)
        j = np.asarray(j, np.int64)
        p, n, u, v, h = self.points.points[j], self._n[j], self._u[j], self._v[j], self._h[j]
        r = q - p
        a, c, d = np.sum(r * u, 1), np.sum(r * v, 1), np.sum(r * n, 1)
        ac, cc = np.clip(a, -h[:, 0], h[:, 0]), np.clip(c, -h[:, 1], h[:, 1])
        clamped = (ac != a) | (cc != c)
        foot = p + ac[:, None] * u + cc[:, None] * v
        off = np.linalg.norm(q - foot, axis=1)
        dist = np.where(clamped, np.where(d < 0, -off, off), d)
        mp = self.points
        return Closest(foot, n.copy(), dist, np.asarray(mp.face, np.int32)[j],
                       np.asarray(mp.uv, np.float64)[j], j,
                       clamped & np.asarray(mp.boundary, bool)[j])
