"""Connected components of points linked by pairs: the clustering of the inspection's regions,
material, floating surfaces and coverage gaps, and of the characteristics' outlier groups
(:mod:`shapeverify.characteristics.support`).  In ``measures`` so that both may use it (the
characteristics may not import the inspection package: ``tests/test_import_cycles.py``)."""
from __future__ import annotations

import numpy as np

from ._component_kernels import component_labels
from ._grid_kernels import kernel_array

__all__ = ["linked_components"]


def linked_components(n: int, pairs: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of ``n`` points linked by ``pairs`` ((k, 2) indices, e.g. from
    ``cKDTree.query_pairs``): ``(count, labels (n,))``, the labels of
    ``scipy.sparse.csgraph.connected_components`` without its set-up cost.

    >>> linked_components(4, np.array([[2, 1]]))[1].tolist()
    [0, 1, 1, 2]
    """
    labels = np.empty(n, np.int32)
    pairs = kernel_array(np.asarray(pairs).reshape(-1, 2), np.int64)
    return int(component_labels(int(n), pairs, labels)), labels
