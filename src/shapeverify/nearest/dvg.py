"""The Distance Varying Grid (DVG) tree: nearest model point in a few memory reads (Paper I).

Works on plain arrays, independent of CAD: model points (N, 3), their neighbour graph and,
for the fast answer, their tangent patches.

Model points
------------
Each model point is one 128-byte record (:func:`make_records`): coordinates, its 8 nearest
neighbours (the *graph*) with their offsets quantised to int16, and its tangent patch (normal,
tangent_u, half extents).  A *walk* moves from a point to the neighbour that looks closest to
the query, confirmed with exact coordinates, until no neighbour is closer: a local minimum of
the distance, found by reading one record per move.

Tree
----
A regular *top grid* covers the model's bounding box expanded by the maximum query distance
(cells of 8 spacings, coarser if the grid would get too large).  Cells are refined
octree-style down to half a spacing.  At build time the exact nearest model point of every cell
vertex is computed (a kd-tree on the top grid, then brute force over candidate lists inherited
from the parent cell: :mod:`shapeverify.nearest.dvg_build`).  A cell is

* **FAR** when all its vertices are farther than ``reach + r`` from the model (r: half
  its diagonal), so no point of it is within ``reach``; queries there fall back to an
  exact kd-tree query, so no answer is ever wrong;
* a **leaf with one seed** (the end of a walk towards the cell centre) when the walk from that
  seed reaches the exact nearest point of each of the 8 vertices in at most ``max_moves`` (2)
  moves;
* otherwise the vertices' closest points *disagree*: the cell is large compared with the local
  spacing (too many moves), or it straddles a medial surface (two sheets of the model: the two
  sides of a thin blade, a concave corner) where a walk stops on the wrong sheet.  Cells no
  larger than 2 spacings then become **multi-seed leaves** (the seed plus the nearest points of
  the failing vertices, at most 4) if walking from every seed is right at the 8 vertices and at
  7 more samples (centre and face centres); else they are **refined**.  On the last level they
  become multi-seed leaves anyway.

A query descends from its top cell to the leaf in O(depth) (each level doubles the fractional
cell coordinate, exact in binary floating point, so points on vertices and cell faces are
handled consistently), walks from the seed(s) and returns the closest end point.  Because the
Voronoi cell of a model point is convex, a leaf whose 8 vertices share their nearest point (the
seed) is exact everywhere inside; in the others the walk is verified at the samples, and over
random queries it returns the true nearest model point for more than 99.9 % of them (measured
in ``tests/test_dvg.py`` and ``benchmarks/bench_closest.py``); the rest lie within a spacing.

Cell sizes thus vary with the distance to the model and its shape, as the name says: small
near medial surfaces and where the spacing is fine, as large as the walk allows elsewhere.

References
----------
P. Bergström, O. Edlund, I. Söderkvist, "Repeated surface registration for on-line use",
Int. J. Adv. Manuf. Technol. 54 (2011) 677-689 (Paper I of the thesis), §3.2 and §4.
Q. Meyer et al., "On floating-point normal vectors", Computer Graphics Forum 29 (2010)
(octahedral normal codes).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np
from shapeverify._lazy import cKDTree

from .._arrays import check_points
from .._renamed import renamed_keywords
from . import _build_kernels, _kernels
from ._threads import run_chunks
from .dvg_build import TreeLimits, build_tree

logger = logging.getLogger(__name__)

__all__ = ["DVG", "DVGTree", "QueryAnswer", "build_tree", "neighbor_graph", "make_records", "morton_order",
           "check_points"]

# walk budget at query time: far above what the build allows (max_moves), so a query is never
# cut short in practice; only a safety net against pathological graphs.
_QUERY_MOVES = 256


def morton_order(points: np.ndarray, cell: float) -> np.ndarray:
    """Permutation sorting points along a Morton (Z-order) curve of a grid of size ``cell``.

    Neighbouring model points then sit close in memory, which keeps queries cache friendly.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    g = np.floor((p - p.min(axis=0)) / cell).astype(np.int64)
    g >>= max(0, int(g.max()).bit_length() - 21)  # at most 21 bits per axis
    from ._knn_kernels import morton_codes
    return np.argsort(morton_codes(np.ascontiguousarray(g)), kind="stable")


def neighbor_graph(points: np.ndarray, k: int = _kernels.K,
                   tree: cKDTree | None = None, spacing: float | None = None) -> np.ndarray:
    """The k nearest other model points of each model point: (N, k) int32, -1 padded.

    Duplicated points are all listed, so a walk can pass them.  With the model point
    ``spacing`` given, found on a grid of cells of twice the spacing (:mod:`._knn_kernels`,
    3-4x less CPU than the kd-tree at 1M points); points with a near tie in their distances
    ask the kd-tree, so the graph is the kd-tree's either way.
    """
    n = points.shape[0]
    kk = min(k, n - 1)
    out = np.full((n, k), -1, dtype=np.int32)
    if kk <= 0:
        return out
    if spacing is not None and not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be finite and > 0, got {spacing!r}")
    tree = cKDTree(points) if tree is None else tree
    ask = np.arange(n)
    if spacing is not None and kk == k and n > 4 * k:
        ask = _grid_graph(points, k, float(spacing), out)
    for lo in range(0, ask.size, 1 << 16):  # in chunks: no (N, k + 1) temporaries
        sel = ask[lo:lo + (1 << 16)]
        _, idx = tree.query(points[sel], k=kk + 1, workers=-1)
        idx = idx.reshape(sel.size, kk + 1)
        # drop each point itself (normally column 0; with duplicates it may be elsewhere)
        not_self = idx != sel[:, None]
        order = np.argsort(~not_self, axis=1, kind="stable")[:, :kk]
        out[sel, :kk] = np.take_along_axis(idx, order, axis=1)
    return out


def _grid_graph(points, k, spacing, out):
    """The graph rows of the points without near ties (:func:`._knn_kernels.knn`) into
    ``out``; returns the other points' indices."""
    from . import _knn_kernels as _kk
    from ._threads import run_chunks

    pts = np.ascontiguousarray(points, dtype=np.float64)
    lo = pts.min(axis=0)
    cell = 2.0 * spacing
    if np.prod((pts.max(axis=0) - lo) / cell + 2.0) > 2.0**62:  # cell keys would overflow
        return np.arange(pts.shape[0])
    grid = _kk.grid_cells(pts, lo, cell)
    tie = np.empty(pts.shape[0], dtype=np.bool_)

    def one(a, b):
        for c in range(a, b, 1 << 15):
            d = min(b, c + (1 << 15))
            idx = np.empty((d - c, k + 2), dtype=np.int64)
            d2 = np.empty((d - c, k + 2))
            _kk.knn(pts, lo, cell, *grid, k + 1, c, d, idx, d2, tie[c:d])
            out[c:d] = idx[:, 1:k + 1]  # column 0: the point itself (no tie at 0)

    run_chunks(one, pts.shape[0], 1 << 15)
    return np.flatnonzero(tie)


def oct_encode(v: np.ndarray) -> np.ndarray:
    """Octahedral codes (N, 2) in [-1, 1]^2 of unit vectors (N, 3) (Meyer et al. 2010)."""
    v = np.asarray(v, dtype=np.float64)
    l1 = np.abs(v).sum(axis=1)
    l1[l1 == 0] = 1.0
    x, y, z = (v / l1[:, None]).T
    sx = np.where(x >= 0, 1.0, -1.0)
    sy = np.where(y >= 0, 1.0, -1.0)
    neg = z < 0
    ox = np.where(neg, (1 - np.abs(y)) * sx, x)
    oy = np.where(neg, (1 - np.abs(x)) * sy, y)
    return np.column_stack([ox, oy])


def make_records(points: np.ndarray, graph: np.ndarray, frames: np.ndarray | None = None,
                 ) -> np.ndarray:
    """Pack model points into 64-byte aligned 128-byte records (N + 1, 16) float64.

    Parameters
    ----------
    points : (N, 3) float64
    graph : (N, K) int32 neighbours (-1 where missing)
    frames : (N, 8) normal, tangent_u, half_u, half_v, or None (zeros)

    See :mod:`shapeverify.nearest._kernels` for the layout (row N is the far sentinel).
    """
    k = _kernels
    n = points.shape[0]
    rec = aligned_empty((n + 1, 16), np.float64)
    rec[...] = 0.0
    rf, ri, rh, rs = views(rec)
    rf[:n, :3] = points
    rf[n, :3] = k.SENTINEL
    ri[n, k.NBR:k.NBR + k.K] = n
    _build_kernels.fill_neighbours(np.ascontiguousarray(points, dtype=np.float64),
                                   np.ascontiguousarray(graph), k.NBR, k.OFF, k.QSTEP,
                                   ri, rh, rs)
    if frames is not None:
        fr = np.asarray(frames, dtype=np.float64)
        # in chunks: oct_encode's temporaries on all 1M frames at once set the preparation's
        # peak memory (about 60 MiB above the records)
        for a in range(0, n, _CHUNK):
            b = min(n, a + _CHUNK)
            rs[a:b, k.NRM:k.NRM + 2] = oct_encode(fr[a:b, 0:3])
            rh[a:b, k.TAN:k.TAN + 2] = np.rint(oct_encode(fr[a:b, 3:6]) * 32767.0)
            rs[a:b, k.EXT:k.EXT + 2] = fr[a:b, 6:8]
    return rec


_CHUNK = 1 << 16    # rows of frames encoded at a time


_NO_ROWS = np.zeros((0, 4), dtype=np.int32)
_NO_BOUNDARY = np.zeros(0, dtype=np.bool_)


def writable(a: np.ndarray, dtype) -> np.ndarray:
    """``a`` itself when it is a C-contiguous writable array of ``dtype``, else such a copy
    (the kernels are compiled for writable arrays only: a read-only one would compile them
    again)."""
    if a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=dtype, order="C")


def views(rec: np.ndarray):
    """The four typed views (float64, int32, int16, float32) of a record array."""
    return (rec, rec.view(np.int32), rec.view(np.int16), rec.view(np.float32))


def record_views(rec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3) view, neighbours (N + 1, K) int32 view) of a record array."""
    return rec[:-1, :3], rec.view(np.int32)[:, _kernels.NBR:_kernels.NBR + _kernels.K]


def aligned_empty(shape, dtype, align: int = 64) -> np.ndarray:
    """An uninitialised C-contiguous array whose data starts on an ``align``-byte boundary."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape)) * dtype.itemsize
    buf = np.empty(nbytes + align, dtype=np.uint8)
    off = (-buf.ctypes.data) % align
    return buf[off:off + nbytes].view(dtype).reshape(shape)


#: the reach's key among the tree's saved arrays (``tree_max_distance`` in a ``.svm``): the
#: file format keeps its old name (deprecated in the API) so that files of every version load
_REACH_KEY = "max_distance"


@dataclass(frozen=True, eq=False, repr=False)
class DVGTree:
    """The arrays of a built DVG tree (layout in :mod:`shapeverify.nearest._kernels`).

    Attributes
    ----------
    origin : (3,) float64     lower corner of the top grid
    cell : float              top grid cell size (mm)
    dims : (3,) int64         top grid cells per axis
    nodes : (T,) int32        top grid codes followed by child blocks of 8
    lists : (L,) int32        seed lists of multi-seed leaves (count, indices...)
    n_points : int            number of model points the tree refers to
    reach : float             queries within it are answered by the tree (``max_distance``:
                              its deprecated old name)
    depth : int               deepest level below the top grid
    """

    origin: np.ndarray
    cell: float
    dims: np.ndarray
    nodes: np.ndarray
    lists: np.ndarray
    n_points: int
    reach: float
    depth: int

    @property
    def max_distance(self) -> float:
        """Deprecated old name of :attr:`reach` (a :class:`DeprecationWarning`)."""
        warnings.warn("DVGTree.max_distance is now called DVGTree.reach (the old name will go)",
                      DeprecationWarning, stacklevel=2)
        return self.reach

    @property
    def nbytes(self) -> int:
        return int(self.nodes.nbytes + self.lists.nbytes + self.origin.nbytes + self.dims.nbytes)

    def arrays(self) -> dict:
        """Plain arrays for saving (see :meth:`from_arrays`)."""
        return {"origin": self.origin, "cell": np.float64(self.cell), "dims": self.dims,
                "nodes": self.nodes, "lists": self.lists, "n_points": np.int64(self.n_points),
                _REACH_KEY: np.float64(self.reach), "depth": np.int64(self.depth)}

    @classmethod
    def from_arrays(cls, a) -> "DVGTree":
        return cls(np.ascontiguousarray(a["origin"], np.float64), float(a["cell"]),
                   np.ascontiguousarray(a["dims"], np.int64),
                   np.ascontiguousarray(a["nodes"], np.int32),
                   np.ascontiguousarray(a["lists"], np.int32), int(a["n_points"]),
                   float(a[_REACH_KEY]), int(a["depth"]))

    def locate(self, queries: np.ndarray) -> np.ndarray:
        """Leaf code of each (validated, (N, 3) float64) query; -1 = FAR."""
        out = np.empty(queries.shape[0], dtype=np.int64)
        for i in range(queries.shape[0]):
            q = queries[i]
            out[i] = _kernels.locate(q[0], q[1], q[2], self.origin, self.cell, self.dims,
                                     self.nodes)
        return out

    def __repr__(self) -> str:
        return (f"DVGTree(top={tuple(int(x) for x in self.dims)}, cell={self.cell:.4g}, "
                f"depth={self.depth}, nodes={self.nodes.shape[0]}, "
                f"list_entries={self.lists.shape[0]}, reach={self.reach:.4g}, "
                f"{self.nbytes / 2**20:.1f} MiB)")


@dataclass(frozen=True, eq=False)
class QueryAnswer:
    """Everything :meth:`DVG.query` answers for N queries.

    Attributes
    ----------
    index : (N,) int64              nearest model point
    d2 : (N,) float64               squared distance to it (mm^2)
    foot : (M, 3) float64           projection onto its tangent patch, clamped to the patch
    distance : (M,) float64         signed distance to the foot (+ on the normal's side, mm)
    clamped : (M,) bool             the projection was clamped to the patch's extents
    normal : (M, 3) float64         the patch's unit normal
    face : (R,) int32               the nearest model point's face
    uv : (R, 2) float64             its (u, v) (stored in float32)
    on_boundary : (R,) bool         clamped and the model point lies on a free edge

    M = N with patches, else 0; R = M when the rows were given, else 0.
    """

    index: np.ndarray
    d2: np.ndarray
    foot: np.ndarray
    distance: np.ndarray
    clamped: np.ndarray
    normal: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    on_boundary: np.ndarray


class DVG:
    """Model points with their neighbour graph and tangent patches, and the DVG tree.

    Parameters
    ----------
    rec : (N + 1, 16) float64 records (:func:`make_records`), 64-byte aligned
    tree : DVGTree

    Use :meth:`build` to make one from points.
    """

    def __init__(self, rec: np.ndarray, tree: DVGTree):
        if not (rec.flags.writeable and rec.flags.c_contiguous and rec.dtype == np.float64):
            rec, rec0 = aligned_empty(rec.shape, np.float64), rec
            rec[...] = rec0
        self.rec = rec
        self.tree = tree
        self._kd = None
        # what the query kernel reads, as one named tuple of C-contiguous writable arrays: one
        # compiled version of the kernel, whether the arrays come from prepare or from a file
        self._arrays = _kernels.TreeArrays(
            writable(tree.origin, np.float64), float(tree.cell), writable(tree.dims, np.int64),
            writable(tree.nodes, np.int32), writable(tree.lists, np.int32), *views(rec),
            _NO_ROWS, _NO_BOUNDARY)

    @classmethod
    @renamed_keywords(max_distance="reach")
    def build(cls, points, spacing: float, reach: float, frames=None, *,
              max_moves: int = 2, workers: int = -1) -> "DVG":
        """Build from (N, 3) points (kept in the given order) and optional (N, 8) frames.

        ``frames`` rows: unit normal (3), unit tangent_u (3), half extents along tangent_u
        and tangent_v (2); without them the patches are empty (the fast answer is then the
        nearest model point itself).

        Raises
        ------
        ValueError
            For bad points (shape, NaN, empty), frames of the wrong shape, or a spacing or
            reach that is not finite and > 0.
        """
        pts = check_points(points, allow_empty=False)
        for name, val in (("spacing", spacing), ("reach", reach)):
            if not (np.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be finite and > 0, got {val!r}")
        if frames is not None:
            frames = np.asarray(frames, dtype=np.float64)
            if frames.shape != (pts.shape[0], 8) or not np.all(np.isfinite(frames)):
                raise ValueError(f"frames must be finite with shape (N, 8) = "
                                 f"({pts.shape[0]}, 8), got {frames.shape}")
        kd = cKDTree(pts)
        rec = make_records(pts, neighbor_graph(pts, tree=kd, spacing=spacing), frames)
        return cls.from_records(rec, spacing, reach, kd, max_moves=max_moves,
                                workers=workers)

    @classmethod
    def from_records(cls, rec, spacing: float, reach: float, kd: cKDTree, *,
                     max_moves: int = 2, workers: int = -1) -> "DVG":
        """The second half of :meth:`build`: the tree over records made by
        :func:`make_records` (``kd``: a cKDTree over their points).  A caller that made the
        records itself can free the points and frames they came from before the tree, the
        build's memory peak (``prepare`` does)."""
        tree = build_tree(rec, float(spacing), float(reach), kd=kd, workers=workers,
                          limits=TreeLimits(max_moves=max_moves))
        out = cls(rec, tree)
        out._kd = kd
        return out

    @property
    def points(self) -> np.ndarray:
        """(N, 3) model point coordinates (a view)."""
        return self.rec[:-1, :3]

    @property
    def n_points(self) -> int:
        return self.rec.shape[0] - 1

    @property
    def graph(self) -> np.ndarray:
        """(N, K) int32 neighbours (a view; a point lists itself where it has fewer)."""
        return record_views(self.rec)[1][:-1]

    def frames(self) -> np.ndarray:
        """(N, 11) float64: normal, tangent_u, tangent_v, half_u, half_v (decoded)."""
        out = np.empty((self.n_points, 11))
        _, _, rh, rs = views(self.rec)
        _kernels.decode_frames(rs, rh, out)
        return out

    def normals(self, idx) -> np.ndarray:
        """(M, 3) unit normals of the model points ``idx`` (decoded)."""
        idx = np.ascontiguousarray(idx, dtype=np.int64)
        out = np.empty((idx.shape[0], 3))
        _, _, rh, rs = views(self.rec)
        _kernels.decode_normals(idx, rs, rh, out)
        return out

    @property
    def nbytes(self) -> int:
        return int(self.rec.nbytes + self.tree.nbytes)

    def kd(self) -> cKDTree:
        """The exact fallback for FAR queries (built on first use)."""
        if self._kd is None:
            self._kd = cKDTree(np.ascontiguousarray(self.points))
        return self._kd

    def query(self, q: np.ndarray, patches: bool, rows=None, boundary=None) -> QueryAnswer:
        """All answers for validated queries q (N, 3) float64 (C-contiguous).

        Returns a :class:`QueryAnswer`; its patch outputs are empty unless ``patches``, its
        face, uv and on_boundary unless ``rows`` (N, 4) int32 (face, u, v as float32 bits,
        other) and ``boundary`` (N,) bool are given.  FAR queries are answered by the kd-tree
        fallback.
        """
        q = writable(q, np.float64)
        n = q.shape[0]
        m = n if patches else 0
        r = 0 if rows is None else m
        A = _kernels.Answers(np.empty(n, dtype=np.int64), np.empty(n), np.empty((m, 3)),
                             np.empty(m), np.empty(m, dtype=np.bool_), np.empty((m, 3)),
                             np.empty(r, dtype=np.int32), np.empty((r, 2)),
                             np.empty(r, dtype=np.bool_))
        T = self._arrays if rows is None else self._arrays._replace(
            rows=writable(rows, np.int32), boundary=writable(boundary, np.bool_))

        n_far = []  # per chunk (list.append is atomic)

        def chunk(a, b):
            n_far.append(_kernels.query_block(q, T, A, a, b, _QUERY_MOVES, patches))

        run_chunks(chunk, n)
        if sum(n_far):  # (no pass over the answers when the tree answered every query)
            far = np.flatnonzero(A.index < 0)
            d, j = self.kd().query(q[far])
            A.index[far] = j
            A.d2[far] = d * d
            _kernels.answer_known(q, far, T, A, patches)
        idx, d2, foot, dist, clamped, normal, face, uv, onb = A
        return QueryAnswer(idx, d2, foot, dist, clamped, normal, face, uv, onb)

    def nearest(self, queries) -> tuple[np.ndarray, np.ndarray]:
        """Nearest model point: (index (N,) int64, distance (N,) float64).

        Raises ValueError for queries that are not finite (N, 3).
        """
        q = check_points(queries, "queries")
        a = self.query(q, False)
        return a.index, np.sqrt(a.d2)

    def closest_on_patches(self, queries):
        """Fast closest point: projection onto the tangent patch of the nearest model point.

        Returns (index (N,), foot (N, 3), signed distance (N,), clamped (N,) bool,
        normal (N, 3)).  Raises ValueError for bad queries.
        """
        q = check_points(queries, "queries")
        a = self.query(q, True)
        return a.index, a.foot, a.distance, a.clamped, a.normal

    def __repr__(self) -> str:
        return (f"DVG(n_points={self.n_points}, "
                f"{self.nbytes / max(1, self.n_points):.1f} bytes/point, {self.tree!r})")
