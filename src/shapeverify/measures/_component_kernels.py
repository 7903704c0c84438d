"""numba kernel of the connected components of points linked by pairs (private; callers
validate their input; :func:`shapeverify.measures.components.linked_components` is the API).

``component_labels`` gives the labels of ``scipy.sparse.csgraph.connected_components`` on the
undirected graph (components numbered in the order of their lowest point index) by union-find,
without building a sparse matrix (whose set-up costs about half a millisecond however small the
graph).
"""
import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def component_labels(n, pairs, labels):
    """Write the component of each of ``n`` points into ``labels`` and return their number.

    n : int; pairs : (k, 2) int64 point indices in 0..n-1; labels : (n,) int32, written.
    """
    parent = np.arange(n)
    for k in range(pairs.shape[0]):
        a = _root(parent, pairs[k, 0])
        b = _root(parent, pairs[k, 1])
        if a != b:
            if a < b:
                parent[b] = a
            else:
                parent[a] = b
    label_of = np.full(n, -1, np.int64)
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if label_of[r] < 0:
            label_of[r] = count
            count += 1
        labels[i] = label_of[r]
    return count
