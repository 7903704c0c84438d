"""``prepare(model)``: the closest-point structure of a model, its answers, and its file.

:func:`prepare` samples the model (:meth:`Model.sample`), orders the model points along a
Morton curve, links each to its 8 nearest neighbours and builds the DVG tree
(:mod:`shapeverify.nearest.dvg`).  :meth:`Prepared.closest` answers

* fast (``exact=False``): the projection onto the tangent patch of the nearest model point,
  clamped to the patch (Paper I §4); the error falls with the square of the spacing;
* exact (``exact=True``): refined on the model itself (:mod:`shapeverify.nearest.exact`).

Defaults (``size`` = bounding-box diagonal of the model, mm)
-------------------------------------------------------------
``spacing = size / 500`` (coarser where the model needs less:
:func:`shapeverify.cad.sampling.needed_spacing`: a mesh's triangles, a cloud's own spacing, a
solid CAD part up to 2x coarser, to about 150,000 model points) and ``reach = 0.03 * size``
(3 % of the size = 15 spacings; at most 15 and at least 2 spacings for other spacings).  Queries
farther than ``reach`` from the model are still
answered exactly, by a kd-tree (slower).

Memory (:attr:`Prepared.nbytes`) per model point: a 128-byte record (coordinates, 8
neighbours with quantised offsets, the tangent patch), a 16-byte row (face, (u, v) in float32
-- the start of the exact refinement --, the other-face link), the boundary flag and the tree
(typically 10-50 bytes).

The ``.svm`` file is one uncompressed ``.npz`` archive (read without pickle): these arrays
plus the model (:func:`shapeverify.cad.persist.model_to_arrays`).  Its header (``meta``) holds
the SHA-256 of all other arrays (``sha256``, :func:`._svm_checks.payload_digest`); loading
compares it (files written before it existed load without), then checks the arrays' sizes,
index ranges and that the tree is a tree (:func:`._svm_checks.check_structure`), so a damaged or
crafted file is a :class:`~shapeverify.errors.ModelFileError`, never a crash or an endless
query.  A CAD model's file also holds the exact refiner's patch bounds (``exact_patch_*``,
:class:`~shapeverify.nearest.patches.PatchBounds`; ``meta["exact_patches"]``: their rule and
patch size), checked the same way (:func:`~shapeverify.nearest.patches.check_arrays`): the
first exact query of a process does not make them again (0.14 s of the first ``inspect`` of
the example panel).  Files without them, or of another rule, make them on first use.

References
----------
P. Bergström, O. Edlund, I. Söderkvist, "Repeated surface registration for on-line use",
Int. J. Adv. Manuf. Technol. 54 (2011) 677-689 (Paper I of the thesis).
"""

from __future__ import annotations

import io
import json
import logging
import os
import time
import warnings
import zipfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from shapeverify._lazy import cKDTree

from shapeverify._renamed import renamed_keywords

from . import dvg as _dvg
from ._svm_checks import check_structure, payload_digest
from ._malloc import PREPARE_MMAP_THRESHOLD, lean_malloc, release_memory  # noqa: F401
from .exact import for_model, patch_size
from .patches import PatchBounds

logger = logging.getLogger(__name__)

__all__ = ["Closest", "Prepared", "prepare", "load_prepared", "default_spacing",
           "default_reach", "FORMAT_TAG", "FORMAT_VERSION"]

FORMAT_TAG = "shapeverify-prepared"
FORMAT_VERSION = 1


def default_spacing(size: float) -> float:
    """Model point spacing used when none is given: size / 500 (1 mm for a model of size 0).

    Relative to the size, so that any part gets a similar number of model points (a sheet
    about 1e5, a solid part a few 1e5).
    """
    return float(size / 500.0) if size > 0 else 1.0


def default_reach(size: float, spacing: float) -> float:
    """Tree reach used when none is given: 3 % of the size, at most 15 and at least 2 spacings.

    At the default spacing (size / 500) 3 % of the size is 15 spacings. A finer spacing keeps
    the reach at 15 spacings: a 3 % reach at a third of the default spacing asked the tree for
    so many cells that it stopped refining (its memory budget) and near-surface queries got
    12x slower (1.7 us instead of 0.14 us on the panel at 0.35 mm); queries beyond the reach
    are still answered exactly, by the kd-tree.

    >>> [round(default_reach(360.0, h), 6) for h in (0.72, 0.35, 10.0)]
    [10.8, 5.25, 20.0]
    """
    reach = 0.03 * size
    if 15.0 * spacing < reach * (1.0 - 1e-9):   # (not an ulp below 3 % at the default spacing)
        reach = 15.0 * spacing
    return float(max(reach, 2.0 * spacing))


def default_max_distance(size: float, spacing: float) -> float:
    """Deprecated old name of :func:`default_reach` (a :class:`DeprecationWarning`)."""
    warnings.warn("default_max_distance() is now called default_reach() (the old name will go)",
                  DeprecationWarning, stacklevel=2)
    return default_reach(size, spacing)


@dataclass(frozen=True, eq=False, repr=False)
class Closest:
    """Closest points on the model for N query points.

    Attributes
    ----------
    points : (N, 3) float64       foot points on the model
    normals : (N, 3) float64      outward unit normals at the foot points
    distances : (N,) float64      signed distances, + on the normal's side (outside)
    face : (N,) int32             face (CAD), triangle (mesh) or -1 (point cloud)
    uv : (N, 2) float64           surface parameters of the foot (fast mode: those of the
                                  nearest model point, stored in float32); barycentric for
                                  meshes; 0 for clouds
    index : (N,) int64            nearest model point (row of ``Prepared.points``)
    on_boundary : (N,) bool       foot on a free edge of the model (the part's outline)
    """

    points: np.ndarray
    normals: np.ndarray
    distances: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    index: np.ndarray
    on_boundary: np.ndarray

    def __len__(self) -> int:
        return self.distances.shape[0]

    def __repr__(self) -> str:
        n = len(self)
        if n == 0:
            return "Closest(n=0)"
        d = self.distances
        return (f"Closest(n={n}, distance=[{d.min():.4g}, {d.max():.4g}] mm, "
                f"mean |d|={np.abs(d).mean():.4g} mm, on_boundary={int(self.on_boundary.sum())})")


class Prepared:
    """A model prepared for closest-point queries (use :func:`prepare` or :func:`load_prepared`).

    Attributes
    ----------
    model : Model
    model_spacing : float         model point spacing (mm); :attr:`spacing` is the same (its
                                  older name, kept: the model's spacing, not a scan's)
    reach : float                 reach of the DVG tree (mm): queries within it use the tree;
                                  :attr:`max_distance` is its deprecated old name
    tree : DVGTree
    points : ModelPoints          the model points in the order ``Closest.index`` refers to
                                  (Morton order, not that of ``model.sample``), assembled from
                                  the compact storage on first access and kept (the same object
                                  every time): normals to ~1e-7, tangent_u to ~1e-4 rad, (u, v)
                                  in float32 precision

    A :class:`~shapeverify.nearest.protocol.ClosestPoints` (what registration and inspection
    read of it).
    """

    def __init__(self, model, fast: _dvg.DVG, rows: np.ndarray, boundary: np.ndarray,
                 spacing: float, reach: float):
        self.model = model
        self._fast = fast
        # one 16-byte row per model point: face (int32), u, v (float32), other-face point
        # (int32, -1 if none): what the fast and exact answers read besides the record
        # (writable C-contiguous: the query kernel is compiled for that flavour only)
        rows = _dvg.writable(rows, np.int32)
        boundary = _dvg.writable(boundary, np.bool_)
        self._rows = rows
        self._face = rows[:, 0]
        self._uv = rows.view(np.float32)[:, 1:3]
        self._other = rows[:, 3]
        self._boundary = boundary
        self.model_spacing = float(spacing)
        self.reach = float(reach)
        self._exact = None
        #: the exact refiner's patch bounds read from the ``.svm`` file (None: made on first use)
        self._stored_patches = None
        #: (4, 4) float64 or None: the fixture pose T_model_scan of a production line where every
        #: part sits in the same place (``prepare --fixture T.json``); ``inspect`` starts there
        #: when no ``init`` is given.  Saved in the ``.svm``.
        self.fixture = None

    # ---------------------------------------------------------------------------- views
    @property
    def spacing(self) -> float:
        """The model point spacing (mm): :attr:`model_spacing` (this older name is kept)."""
        return self.model_spacing

    @property
    def max_distance(self) -> float:
        """Deprecated old name of :attr:`reach` (a :class:`DeprecationWarning`)."""
        warnings.warn("Prepared.max_distance is now called Prepared.reach (the old name will go)",
                      DeprecationWarning, stacklevel=2)
        return self.reach

    @property
    def tree(self) -> _dvg.DVGTree:
        return self._fast.tree

    @property
    def n_points(self) -> int:
        return self._rows.shape[0]

    @cached_property
    def points(self):
        """The model points (:class:`~shapeverify.cad.model.ModelPoints`), assembled from the
        tree's records on first access and kept (the same object every time).  (Its boundary
        is a copy: ModelPoints makes its arrays read-only, the query kernel reads this one.)"""
        from shapeverify.cad.model import ModelPoints

        fr = self._fast.frames()
        return ModelPoints(points=np.array(self._fast.points), normals=fr[:, 0:3],
                           face=self._face, uv=self._uv, tangent_u=fr[:, 3:6],
                           tangent_v=fr[:, 6:9], half_extent=fr[:, 9:11],
                           boundary=self._boundary.copy(), spacing=self.spacing)

    @property
    def nbytes(self) -> int:
        """Bytes held by the closest-point structure (model points, patches, tree).

        The CAD model itself (NURBS faces) is not counted, nor the tables the exact mode
        builds on first use (:attr:`exact_nbytes`).
        """
        return int(self._fast.nbytes + self._rows.nbytes + self._boundary.nbytes)

    @property
    def memory_per_point(self) -> float:
        """:attr:`nbytes` per model point."""
        return self.nbytes / max(1, self.n_points)

    @property
    def exact_nbytes(self) -> int:
        """Bytes of the exact-mode tables (0 until the first exact query)."""
        return int(getattr(self._exact, "nbytes", 0))

    # -------------------------------------------------------------------------- queries
    def closest(self, points, exact: bool = False) -> Closest:
        """Closest points on the model.

        Parameters
        ----------
        points : (N, 3) array_like (a single (3,) point is accepted)
        exact : bool
            False: projection onto the tangent patch of the nearest model point (fast,
            error of order spacing^2 x curvature).  True: refined on the model (NURBS point
            inversion with trims, triangles, or a quadric through the nearest cloud points).

        Returns
        -------
        Closest

        Raises
        ------
        ValueError
            If ``points`` is not (N, 3) or holds NaN or inf.
        """
        q = _dvg.check_points(points, "points")
        if exact:
            return self._closest_exact(q)
        a = self._fast.query(q, True, self._rows, self._boundary)
        return Closest(a.foot, a.normal, a.distance, a.face, a.uv, a.index, a.on_boundary)

    def _closest_exact(self, q: np.ndarray) -> Closest:
        if self._exact is None:
            t0 = time.perf_counter()
            self._exact = for_model(self.model, self.spacing, self._stored_patches)
            logger.debug("exact refiner for %s ready in %.2f s", self.model.kind,
                         time.perf_counter() - t0)
        idx, _ = self._fast.nearest(q)
        foot, normals, dist, face, uv, onb = self._exact.refine(
            q, idx, self._fast, self._face, self._uv, self._other)
        return Closest(foot, normals, dist, face, uv, idx, onb)

    # ----------------------------------------------------------------------------- file
    def save(self, path) -> None:
        """Write everything (model included) to one ``.svm`` file (uncompressed npz, no
        pickle); :func:`load_prepared` reads it back.

        Raises
        ------
        OSError
            If the file cannot be written.
        """
        from shapeverify.cad.persist import model_to_arrays

        # "max_distance": the reach under its old key, for readers before issue 31 (deprecated)
        meta = {"format": FORMAT_TAG, "version": FORMAT_VERSION, "spacing": self.model_spacing,
                "reach": self.reach, "max_distance": self.reach, "n_points": self.n_points,
                "fixture": None if self.fixture is None else np.asarray(self.fixture).tolist()}
        arrays = {"meta": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8),
                  "rec": self._fast.rec, "rows": self._rows, "boundary": self._boundary}
        arrays.update({f"tree_{k}": np.asarray(v) for k, v in self._fast.tree.arrays().items()})
        arrays.update({f"model_{k}": v for k, v in model_to_arrays(self.model).items()})
        patches = self._patch_bounds()
        if patches is not None:     # what the first exact query would make again: stored
            arrays.update({f"{_PATCH_KEY}{k}": v for k, v in patches.to_arrays().items()})
            meta["exact_patches"] = {"rule": PatchBounds.RULE,
                                     "size": patch_size(self.model_spacing)}
        meta["sha256"] = payload_digest(arrays)
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        path = Path(os.fspath(path))
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)

    def _patch_bounds(self):
        """A CAD model's patch bounds for the exact refiner (made now if not yet); None for
        other kinds or a model without faces."""
        if getattr(self.model, "kind", "cad") != "cad":
            return None
        if self._exact is None:
            try:
                self._exact = for_model(self.model, self.spacing, self._stored_patches)
            except ValueError:      # no faces: no exact refiner
                return None
        return self._exact.patches

    def __repr__(self) -> str:
        return (f"Prepared(model={self.model!r}, n_points={self.n_points}, "
                f"model_spacing={self.model_spacing:.4g} mm, reach={self.reach:.4g} mm, "
                f"{self.memory_per_point:.0f} bytes/point, depth={self.tree.depth})")


def _frames(mp) -> np.ndarray:
    return np.concatenate([mp.normals, mp.tangent_u, mp.half_extent], axis=1)


def _frames_from_graph(mp, order, pts, graph, spacing) -> np.ndarray:
    """The frames (N, 8) of the model points ``mp`` in ``order`` (points ``pts``), their half
    extents measured from the neighbour ``graph`` of ``pts``
    (:func:`shapeverify.cad.sampling.half_extents_from_graph`)."""
    from shapeverify.cad.sampling import half_extents_from_graph

    frames = np.empty((pts.shape[0], 8))
    frames[:, 0:3] = mp.normals[order]
    frames[:, 3:6] = mp.tangent_u[order]
    frames[:, 6:8] = half_extents_from_graph(pts, frames[:, 3:6], mp.tangent_v[order], spacing,
                                             graph)
    return frames


def _other_face_points(points, face, spacing, kd, radius: float = 3.0, k: int = 32):
    """For each model point, the nearest model point of another face within radius * spacing.

    (N,) int32, -1 where there is none.  Exact mode tries those faces too, so that a query
    near a face border is refined on every face that can hold its closest point.  (Among the
    k nearest model points: the first of another face.)  Only points whose grid cell of side
    ``radius * spacing`` has another face in it or in one of its 26 neighbours can have one;
    they are searched on a grid (:func:`_other_face_on_grid`: about 5x less CPU than the
    kd-tree at 1M points), and the kd-tree is asked only where its order among equal
    distances decides the answer, so the links are the kd-tree's either way.
    """
    n = points.shape[0]
    other = np.full(n, -1, dtype=np.int32)
    kk = min(k, n)
    if kk < 2:
        return other
    cand = np.flatnonzero(_near_other_face(points, face, radius * spacing * (1.0 + 1e-6)))
    if cand.size:
        cand = _other_face_on_grid(points, face, radius * spacing, kk, cand, other)
    for lo in range(0, cand.size, 1 << 15):  # (chunk, k) distances and indices: 16 MB
        sel = cand[lo:lo + (1 << 15)]
        d, j = kd.query(points[sel], k=kk, distance_upper_bound=radius * spacing, workers=-1)
        j = j.reshape(sel.size, kk)
        valid = j < n
        jj = np.where(valid, j, 0)
        diff = valid & (face[jj] != face[sel, None])
        first = np.argmax(diff, axis=1)
        rows = np.arange(sel.size)
        has = diff[rows, first]
        other[sel] = np.where(has, jj[rows, first], -1)
    return other


def _other_face_on_grid(points, face, r, k, cand, other):
    """:func:`_other_face_points` for the points ``cand`` on a grid of cells of side ``r``
    (:func:`._knn_kernels.other_face_first`, the kd-tree's answers) into ``other``; returns
    the points whose answer depends on the kd-tree's order among equal distances, for the
    kd-tree to answer."""
    from . import _knn_kernels as _kk
    from ._threads import run_chunks

    pts = np.ascontiguousarray(points, dtype=np.float64)
    lo = pts.min(axis=0)
    if np.prod((pts.max(axis=0) - lo) / r + 2.0) > 2.0**62:  # cell keys would overflow
        return cand
    grid = _kk.grid_cells(pts, lo, float(r))
    f = np.ascontiguousarray(face, dtype=np.int32)
    ans = np.empty(cand.size, dtype=np.int64)
    flag = np.empty(cand.size, dtype=np.bool_)

    def one(a, b):
        _kk.other_face_first(pts, f, lo, float(r), *grid, cand[a:b], int(k), ans[a:b],
                             flag[a:b])

    run_chunks(one, cand.size, 1 << 14)
    other[cand] = ans
    return cand[flag]


def _near_other_face(points, face, cell):
    """(N,) bool: the point's grid cell (side ``cell``) or one of its 26 neighbours holds a
    point of another face (so every point with another face within ``cell`` is True)."""
    g = np.floor((points - points.min(axis=0)) / cell).astype(np.int64) + 1
    dims = g.max(axis=0) + 2
    key = (g[:, 0] * dims[1] + g[:, 1]) * dims[2] + g[:, 2]
    ukey, inv = np.unique(key, return_inverse=True)
    f = face.astype(np.int64)
    fmin = np.full(ukey.size, np.iinfo(np.int64).max)
    fmax = np.full(ukey.size, np.iinfo(np.int64).min)
    np.minimum.at(fmin, inv, f)
    np.maximum.at(fmax, inv, f)
    lo, hi = fmin.copy(), fmax.copy()
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if dx == dy == dz == 0:
                    continue
                nk = ukey + (dx * dims[1] + dy) * dims[2] + dz
                pos = np.minimum(np.searchsorted(ukey, nk), ukey.size - 1)
                hit = ukey[pos] == nk
                np.minimum(lo, np.where(hit, fmin[pos], lo), out=lo)
                np.maximum(hi, np.where(hit, fmax[pos], hi), out=hi)
    return (lo != hi)[inv.ravel()]


@renamed_keywords(max_distance="reach")
def prepare(model, spacing: float | None = None, reach: float | None = None, *,
            allow_incomplete: bool = False) -> Prepared:
    """Prepare a model for fast closest-point queries (Paper I).

    Parameters
    ----------
    model : Model
        CAD, mesh or point-cloud model (:func:`shapeverify.load_model`).
    spacing : float, optional
        Model point spacing in mm; default ``model.size / 500``, or coarser where
        :func:`shapeverify.cad.sampling.needed_spacing` says the model needs less: about 4
        points per triangle of a mesh, a cloud's own point spacing, and for a solid CAD part
        (whose ``size / 500`` gives 3-5e5 points) the spacing of about 150,000 points, at most
        2x coarser and at most 1/2.5 of its thinnest walls.
    reach : float, optional
        The closest-point structure's reach: queries within this distance (mm) are answered by
        the DVG tree, farther ones by a kd-tree; default
        ``max(min(0.03 * model.size, 15 * spacing), 2 * spacing)``.
        (Not the inspection's evaluation distance, which decides which scan points count.)
    max_distance : float, optional
        Deprecated old name of ``reach`` (a :class:`DeprecationWarning`).
    allow_incomplete : bool, optional
        Prepare a CAD model that lacks faces its file declares
        (:func:`shapeverify.cad.completeness.is_incomplete`); every inspection against it then
        names the missing faces in its reasons.  Default False: such a model is refused.

    Returns
    -------
    Prepared

    Raises
    ------
    ValueError
        If ``spacing`` or ``reach`` is not a finite number > 0, or the model yields no
        model points.
    IncompleteModelError
        The CAD model lacks faces its file declares and ``allow_incomplete`` is False.

    Examples
    --------
    >>> from shapeverify.cad.nurbs import sphere
    >>> from shapeverify.cad.model import Face, Model
    >>> f = Face(sphere(10.0), (np.array([[0, 0], [1, 0], [1, 1], [0, 1.]]),),
    ...          (np.zeros(4, bool),))
    >>> prep = prepare(Model(faces=(f,), source="sphere"), spacing=1.0, reach=3.0)
    >>> near = prep.closest([[0.0, 0.0, 12.0]], exact=True)
    >>> round(float(near.distances[0]), 9)
    2.0
    """
    if not allow_incomplete:
        from shapeverify.cad.completeness import require_complete
        require_complete(model)
    for name, val in (("spacing", spacing), ("reach", reach)):
        if val is not None:
            try:
                ok = np.isfinite(float(val)) and float(val) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"{name} must be a finite number > 0 (mm), got {val!r}; "
                                 "or None for the default")
    t0 = time.perf_counter()
    size = model.size
    if spacing is None:  # no finer than the model's geometry needs (mesh, cloud, solid CAD)
        from shapeverify.cad.sampling import needed_spacing
        h = max(default_spacing(size), needed_spacing(model))
    else:
        h = float(spacing)
    maxd = default_reach(size, h) if reach is None else float(reach)
    # the patches' half extents are measured below from the neighbour graph, which the tree
    # needs anyway (the sampling's own kd-tree search for them would double that work)
    mp = model.sample(h, half_extents=False)
    if len(mp) == 0:
        raise ValueError(f"{model!r} gave no model points at spacing {h} mm")
    t1 = time.perf_counter()
    held = [mp]
    del mp  # _structure frees the sampled model points before the tree
    with lean_malloc():  # the arrays from here on are returned to the system when freed
        face, rows, boundary, fast = _structure(held, h, maxd, model.kind == "cad")
    t2 = time.perf_counter()
    prep = Prepared(model, fast, rows, boundary, h, maxd)
    logger.info("prepared %d model points (spacing %.4g mm, max distance %.4g mm): sampling "
                "%.2f s, tree %.2f s, %.0f bytes/point", face.shape[0], h, maxd, t1 - t0,
                t2 - t1, prep.memory_per_point)
    return prep


def _structure(held, h, maxd, cad):
    """The second half of :func:`prepare`: (face, rows, boundary, DVG) of the sampled model
    points ``held[0]``, which are taken out of ``held`` and freed before the tree (the memory
    peak of the preparation; they live on in the records)."""
    mp = held.pop()
    order = _dvg.morton_order(mp.points, h)
    # DVG.build in two steps (from_records), so that the frames are freed before the tree too
    pts = _dvg.check_points(mp.points[order], allow_empty=False)
    kd = cKDTree(pts)
    graph = _dvg.neighbor_graph(pts, tree=kd, spacing=h)
    frames = _frames_from_graph(mp, order, pts, graph, h)
    if not np.all(np.isfinite(frames)):  # as DVG.build checks
        raise ValueError(f"frames must be finite with shape (N, 8) = ({pts.shape[0]}, 8)")
    rec = _dvg.make_records(pts, graph, frames)
    del graph
    face = np.ascontiguousarray(mp.face[order])
    rows = np.empty((face.shape[0], 4), dtype=np.int32)
    rows[:, 0] = face
    rows.view(np.float32)[:, 1:3] = mp.uv[order]
    boundary = np.ascontiguousarray(mp.boundary[order])
    del mp, pts, order, frames
    release_memory()  # the heap pages of the freed arrays, before the tree
    fast = _dvg.DVG.from_records(rec, h, maxd, kd)
    del rec, kd
    rows[:, 3] = _other_face_points(fast.points, face, h, fast.kd()) if cad else -1
    return face, rows, boundary, fast


#: the prefix of the exact refiner's patch bounds in a ``.svm`` file
_PATCH_KEY = "exact_patch_"


def _read_patches(arrays: dict, info, model, spacing: float, path):
    """The patch bounds a ``.svm`` file stores, checked (a damaged or crafted file: a
    ModelFileError); None when it stores none, or bounds of another rule or patch size (older
    files: made again on first use)."""
    from shapeverify.errors import ModelFileError

    if not arrays or getattr(model, "kind", "cad") != "cad":
        return None
    if not (isinstance(info, dict) and info.get("rule") == PatchBounds.RULE
            and info.get("size") == patch_size(spacing)):
        return None
    try:
        return PatchBounds.from_arrays(arrays, len(model.faces))
    except ValueError as exc:
        raise ModelFileError(f"{path}: .svm file is damaged: {exc}") from None


def load_prepared(source) -> Prepared:
    """Read a ``.svm`` file written by :meth:`Prepared.save`.

    ``source`` is a path, the file's bytes, or a binary file object (e.g. a model shipped to
    a batch worker in memory).  Where :mod:`shapeverify._file_memo` is enabled (the command
    line's resident worker), an unchanged file read before gives the model read then.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ModelFileError
        (a :class:`ValueError`) Not a prepared-model file, damaged (bit flips fail the archive's
        CRC check) or truncated, an unsupported version, or inconsistent arrays.  The message
        names the file and says to run ``shapeverify prepare`` again.
    """
    from shapeverify._file_memo import PREPARED_MODELS

    return PREPARED_MODELS.call(_read_prepared, source)


def _read_prepared(source) -> Prepared:
    """:func:`load_prepared`, read every time."""
    from shapeverify.cad.persist import DAMAGED_FILE_ERRORS, damage_text
    from shapeverify.errors import EmptyModelError, ModelFileError

    if isinstance(source, (bytes, bytearray, memoryview)):
        data, where = bytes(source), "<prepared model bytes>"
    elif hasattr(source, "read"):
        data, where = source.read(), str(getattr(source, "name", "<prepared model file object>"))
        if not isinstance(data, bytes):
            raise TypeError(f"{where}: open the .svm file in binary mode ('rb')")
    else:
        path = Path(os.fspath(source))
        if not path.is_file():
            import errno
            raise FileNotFoundError(errno.ENOENT, f"no such prepared-model file: {path}",
                                    str(path))
        data, where = None, path
    redo = "run `shapeverify prepare CAD -o MODEL.svm` again to make a new one"
    try:
        return _load_prepared(where if data is None else io.BytesIO(data), where,
                              len(data) if data is not None else where.stat().st_size)
    except (ModelFileError, EmptyModelError) as exc:
        raise ModelFileError(f"{exc}; {redo}") from None
    except DAMAGED_FILE_ERRORS as exc:
        raise ModelFileError(f"{where}: not a readable prepared-model (.svm) file, damaged or "
                             f"truncated ({damage_text(exc)}); {redo}") from None


def _load_prepared(src, path, n_bytes: int) -> Prepared:
    from shapeverify.cad.persist import model_from_arrays
    from shapeverify.errors import ModelFileError

    if n_bytes == 0:
        raise ModelFileError(f"{path}: the prepared-model (.svm) file is empty (0 bytes)")
    try:
        z = np.load(src, allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile) as exc:
        raise ModelFileError(f"{path}: not a prepared-model (.svm) file ({exc})") from None
    with z:
        files = set(z.files)
        try:
            meta = json.loads(bytes(z["meta"]).decode())
        except (KeyError, ValueError, UnicodeDecodeError):
            raise ModelFileError(f"{path}: not a prepared-model (.svm) file (no readable meta)") \
                from None
        if meta.get("format") != FORMAT_TAG:
            raise ModelFileError(f"{path}: not a prepared-model (.svm) file (format "
                                 f"{meta.get('format')!r})")
        if meta.get("version") != FORMAT_VERSION:
            raise ModelFileError(f"{path}: .svm version {meta.get('version')!r} is not supported "
                                 f"(this shapeverify reads {FORMAT_VERSION})")
        # (tree_max_distance: the tree's reach; the file key keeps its deprecated old name)
        need = {"rec", "rows", "boundary", "tree_origin", "tree_cell", "tree_dims",
                "tree_nodes", "tree_lists", "tree_n_points", "tree_max_distance", "tree_depth"}
        if not need <= files:
            raise ModelFileError(f"{path}: .svm file is missing {sorted(need - files)}")
        arrays = {k: z[k] for k in files if k != "meta"}
    digest = meta.get("sha256")
    if digest is not None and digest != payload_digest(arrays):
        raise ModelFileError(f"{path}: .svm file is damaged: its content does not match the "
                             "checksum (SHA-256) written with it; the file was changed or "
                             "damaged after it was written")
    try:
        n = int(meta["n_points"])
        # files written before issue 31 name the reach only by its old key (deprecated)
        spacing = float(meta["spacing"])
        reach = float(meta["reach"] if "reach" in meta else meta["max_distance"])
    except (KeyError, TypeError, ValueError):
        raise ModelFileError(f"{path}: .svm file header lacks a valid n_points, spacing or "
                             "reach") from None
    if not (n >= 1 and np.isfinite(spacing) and spacing > 0 and np.isfinite(reach)
            and reach > 0):
        raise ModelFileError(f"{path}: .svm file header is damaged (n_points {n}, spacing "
                             f"{spacing!r}, reach {reach!r})")
    rec0 = arrays.pop("rec")
    if rec0.shape != (n + 1, 16) or rec0.dtype != np.float64:
        raise ModelFileError(f"{path}: .svm file is inconsistent (the records are "
                             f"{rec0.dtype}{rec0.shape}, the header says {n} model points)")
    rec = _dvg.aligned_empty(rec0.shape, np.float64)
    rec[...] = rec0
    del rec0
    for k in ("tree_nodes", "tree_lists"):
        if arrays[k].dtype.kind not in "iu":
            raise ModelFileError(f"{path}: .svm file holds a damaged tree ({k} is "
                                 f"{arrays[k].dtype}, not integers)")
    tree = _dvg.DVGTree.from_arrays({k[5:]: arrays[k] for k in arrays if k.startswith("tree_")})
    rows = np.ascontiguousarray(arrays["rows"], dtype=np.int32)
    boundary = np.ascontiguousarray(arrays["boundary"], dtype=np.bool_)
    model = model_from_arrays({k[6:]: arrays[k] for k in arrays if k.startswith("model_")},
                              where=str(path))
    stored_patches = {k[len(_PATCH_KEY):]: arrays[k] for k in arrays
                      if k.startswith(_PATCH_KEY)}
    del arrays
    if not (rows.shape == (n, 4) and boundary.shape == (n,) and tree.n_points == n):
        raise ModelFileError(f"{path}: .svm file is inconsistent (arrays do not all hold {n} "
                             "model points)")
    # indices that the numeric kernels follow without bounds checks must be in range, and the
    # tree must be a tree (issue 33 row 5: an index out of range crashed, a cycle hung)
    problem = check_structure(tree, rec, rows, model)
    if problem is not None:
        raise ModelFileError(f"{path}: .svm file is damaged: {problem}")
    prep = Prepared(model, _dvg.DVG(rec, tree), rows, boundary, spacing, reach)
    prep._stored_patches = _read_patches(stored_patches, meta.get("exact_patches"), model,
                                         spacing, path)
    fixture = meta.get("fixture")
    if fixture is not None:
        try:
            T = np.asarray(fixture, dtype=np.float64)
        except (TypeError, ValueError):
            T = np.zeros(0)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ModelFileError(f"{path}: .svm file holds a damaged fixture pose")
        prep.fixture = T
    return prep
