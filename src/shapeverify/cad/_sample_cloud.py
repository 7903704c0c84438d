"""Model points of point-cloud models: thinned cloud points with PCA normals (private).

See :mod:`shapeverify.cad.sampling` (*Point-cloud models*).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from shapeverify._lazy import cKDTree

from ._sample_common import _RADIUS, _thin


def _sample_cloud(model, s, rng):
    X = np.asarray(model.vertices, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) == 0:
        raise ValueError(f"point-cloud model has no points (vertices shape {X.shape})")
    extent = float(np.ptp(X, axis=0).max())
    if len(X) < 3 or extent == 0.0:
        what = "is one point" if len(X) == 1 else (
            f"has only {len(X)} points" if len(X) < 3 else f"has {len(X)} points, all the same point")
        raise ValueError(f"point-cloud model {what} ({X[0].round(6).tolist()}): a reference "
                         "needs points spread over the part's surface; check the file")
    given = getattr(model, "cloud_normals", None)
    r = _RADIUS * s
    # 1. thin without normals to half the final radius (cheap normals on fewer points)
    pre = _thin(X, X, 0.5 * r, rng.permutation(len(X)), use_normals=False)
    pre.sort()
    Xp = X[pre]
    if given is not None:
        N = np.asarray(given, dtype=np.float64)[pre]
        N = N / np.linalg.norm(N, axis=1)[:, None]
    else:
        N = _pca_normals(Xp)
    # 2. final thinning with the same-side test
    idx = _thin(Xp, N, r, rng.permutation(len(Xp)))
    idx.sort()
    P, N = Xp[idx], N[idx]
    T = _any_tangent(N)
    n = len(P)
    return P, N, T, np.full(n, -1, np.int32), np.zeros((n, 2)), np.zeros(n, bool)


@njit(cache=True)
def _neighbour_cov(X, nb, out):
    """Covariance (3, 3) of each point's neighbours (rows of nb)."""
    k = nb.shape[1]
    for i in range(X.shape[0]):
        m0 = m1 = m2 = 0.0
        for j in range(k):
            q = nb[i, j]
            m0 += X[q, 0]
            m1 += X[q, 1]
            m2 += X[q, 2]
        m0 /= k
        m1 /= k
        m2 /= k
        c00 = c01 = c02 = c11 = c12 = c22 = 0.0
        for j in range(k):
            q = nb[i, j]
            a = X[q, 0] - m0
            b = X[q, 1] - m1
            c = X[q, 2] - m2
            c00 += a * a
            c01 += a * b
            c02 += a * c
            c11 += b * b
            c12 += b * c
            c22 += c * c
        out[i, 0, 0] = c00
        out[i, 0, 1] = out[i, 1, 0] = c01
        out[i, 0, 2] = out[i, 2, 0] = c02
        out[i, 1, 1] = c11
        out[i, 1, 2] = out[i, 2, 1] = c12
        out[i, 2, 2] = c22


def _pca_normals(X, k=12):
    """Unit normals by PCA of the k nearest points, oriented consistently over the cloud.

    Each connected part of the k-neighbour graph is oriented from one seed -- its point whose
    normal points most clearly away from the cloud's centroid (``|cos|`` of the normal and the
    direction from the centroid largest), taken outward -- along the graph's maximum-agreement
    spanning tree (Hoppe et al. 1992): a normal is flipped to agree with its parent's.  (The
    centroid rule for every point alone flipped normals wherever a sheet or a concavity crosses
    the centroid's level, which turned signed distances inside out patch by patch.)
    """
    k = min(k, len(X))
    if k < 3:
        raise ValueError(f"need at least 3 points to estimate normals, got {len(X)}")
    _, nb = cKDTree(X).query(X, k=k, workers=2)
    nb = np.ascontiguousarray(nb, dtype=np.int64)
    cov = np.empty((len(X), 3, 3))
    _neighbour_cov(X, nb, cov)
    _, vec = np.linalg.eigh(cov)
    N = np.ascontiguousarray(vec[:, :, 0])
    return _orient(X, N, nb)


def _orient(X, N, nb):
    """Normals N flipped to agree along the k-neighbour graph ``nb`` (see :func:`_pca_normals`)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components, \
        minimum_spanning_tree

    n, k = nb.shape
    rows = np.repeat(np.arange(n), k)
    cols = nb.ravel()
    keep = rows != cols
    rows, cols = rows[keep], cols[keep]
    # weight 1 - |cos| (+ a floor: a zero weight would drop the edge from the sparse graph)
    w = 1.0 - np.abs(np.einsum("ij,ij->i", N[rows], N[cols])) + 1e-6
    g = coo_matrix((w, (rows, cols)), shape=(n, n)).tocsr()
    g = g.maximum(g.T)
    tree = minimum_spanning_tree(g)
    tree = tree + tree.T
    radial = X - X.mean(axis=0)
    rl = np.linalg.norm(radial, axis=1)
    conf = np.einsum("ij,ij->i", N, radial) / np.where(rl > 0, rl, 1.0)
    n_comp, label = connected_components(tree, directed=False)
    out = N.copy()
    for c in range(n_comp):
        members = np.flatnonzero(label == c)
        seed = int(members[np.argmax(np.abs(conf[members]))])
        if conf[seed] < 0:
            out[seed] *= -1.0
        order, pred = breadth_first_order(tree, seed, directed=False)
        _propagate(out, order.astype(np.int64), pred.astype(np.int64))
    return out


@njit(cache=True)
def _propagate(N, order, pred):
    """Flip N[i] to agree with N[pred[i]], parents first (BFS ``order``)."""
    for t in range(1, order.shape[0]):
        i = order[t]
        p = pred[i]
        if N[i, 0] * N[p, 0] + N[i, 1] * N[p, 1] + N[i, 2] * N[p, 2] < 0.0:
            N[i, 0] = -N[i, 0]
            N[i, 1] = -N[i, 1]
            N[i, 2] = -N[i, 2]


def _any_tangent(N):
    """A unit vector perpendicular to each normal."""
    a = np.zeros_like(N)
    ax = np.argmin(np.abs(N), axis=1)
    a[np.arange(len(N)), ax] = 1.0
    t = np.cross(N, a)
    return t / np.linalg.norm(t, axis=1)[:, None]
