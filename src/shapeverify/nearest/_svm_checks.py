"""Checks of a ``.svm`` file's arrays before the numeric kernels trust them (private).

The query kernels follow tree codes, seed lists and neighbour indices without bounds checks
(:mod:`shapeverify.nearest._kernels`): a crafted file with a child index out of range made the
process die with SIGSEGV, and a cycle in the tree made a query loop for ever (issue 33 row 5).
:func:`payload_digest` is the SHA-256 that :meth:`Prepared.save` stores in the file's header
(``meta["sha256"]``) and :func:`load_prepared` compares; :func:`check_structure` runs on every
file, with or without that checksum (files written before it existed), in time linear in the
arrays' sizes:

* array shapes against the header's ``n_points`` (done by the caller) and against each other;
* the tree: a finite origin and cell, a top grid no larger than ``nodes``; every internal code
  ``c >= 0`` the start of a whole block of 8 after the top grid, and no block the child of two
  cells -- with the top grid's cells no one's child this makes every path from the top grid
  end (no cycle can be reached: a cycle would need a block with two parents);
* every leaf code a model point or the start of a seed list that lies inside ``lists``, its
  count >= 1, its entries model points;
* the records' neighbour indices, the rows' other-face links and faces (or triangles) in range.
"""

from __future__ import annotations

import numpy as np

from shapeverify.cad.persist import payload_digest  # noqa: F401 - the .svm's checksum

from . import _kernels

__all__ = ["payload_digest", "check_structure"]


def check_structure(tree, rec: np.ndarray, rows: np.ndarray, model) -> str | None:
    """What is wrong with the arrays of a prepared model (None: nothing found).

    Parameters
    ----------
    tree : DVGTree
    rec : (n + 1, 16) float64 records
    rows : (n, 4) int32 rows
    model : Model
    """
    n = rows.shape[0]
    origin, dims, nodes, lists = tree.origin, tree.dims, tree.nodes, tree.lists
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        return "the tree's origin is not 3 finite numbers"
    if not (np.isfinite(tree.cell) and tree.cell > 0):
        return f"the tree's cell size {tree.cell!r} is not a positive number"
    if not (np.isfinite(tree.reach) and tree.reach > 0):
        return "the tree's reach is not a positive number"
    if dims.shape != (3,) or np.any(dims < 1) or np.any(dims > nodes.size):
        return f"the tree's top grid {dims.tolist()} does not fit its {nodes.size} nodes"
    n_top = int(dims[0]) * int(dims[1]) * int(dims[2])
    if n_top > nodes.size or (nodes.size - n_top) % 8:
        return (f"the tree's {nodes.size} nodes are not a top grid of {n_top} cells and blocks "
                "of 8 children")
    if nodes.ndim != 1 or lists.ndim != 1:
        return "the tree's arrays are not 1-D"
    codes = nodes.astype(np.int64)
    inner = codes[codes >= 0]
    if inner.size:
        rel = inner - n_top
        if rel.min() < 0 or np.any(rel % 8) or inner.max() + 8 > nodes.size:
            return "a tree cell's child index is out of range"
        if np.bincount(rel // 8).max() > 1:
            return "the tree is not a tree (a block of cells has two parents: a cycle or a join)"
    leaf = codes[codes <= -2]
    if leaf.size:
        m = -leaf - 2
        if m.max() >= n + lists.size:
            return "a tree leaf names a model point or seed list out of range"
        off = m[m >= n] - n
        if off.size:
            cnt = lists[off].astype(np.int64)
            if cnt.min() < 1 or np.any(off + cnt >= lists.size):
                return "a seed list of the tree runs past the end of its array"
    if lists.size and (lists.min() < 0 or lists.max() > n):
        return "a seed list names a model point out of range"
    nbr = rec.view(np.int32)[:, _kernels.NBR:_kernels.NBR + _kernels.K]
    if nbr.size and (nbr.min() < 0 or nbr.max() > n):
        return "a model point's neighbour index is out of range"
    other = rows[:, 3]
    if n and (other.min() < -1 or other.max() >= n):
        return "a model point's other-face link is out of range"
    face = rows[:, 0]
    if n:
        if model.kind == "cad":
            lo, hi = 0, len(model.faces)
        elif model.kind == "mesh":
            lo, hi = 0, model.triangles.shape[0]
        else:  # a point cloud: the cloud point (or -1)
            lo, hi = -1, max(1, model.vertices.shape[0])
        if face.min() < lo or face.max() >= hi:
            return f"a model point's face index is outside [{lo}, {hi})"
    return None
