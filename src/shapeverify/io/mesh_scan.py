"""Mesh scans: STL / PLY / OBJ triangle meshes that a structured-light scanner delivers, read as
measured points (issue 30, item 1).

A mesh's vertices are not an even sample of the surface: scanner software thins flat areas and
keeps many vertices on curved ones, so counting vertices would weigh the surface unevenly.  Two
readings are offered:

``method="sample"`` (default)
    Points drawn uniformly on the triangles at the mesh's own resolution: one point per
    ``sqrt(3)/2 * s**2`` of area, ``s`` the median edge length (the vertex density of a regular
    triangulation with edges ``s``), each triangle's count rounded stochastically so the density
    is exact on average; seeded, so the same file gives the same points.  Every point lies on the
    measured surface; the density is uniform by area.
``method="vertices"``
    The vertices as stored (those used by a triangle), each with its area weight: a third of the
    area of the triangles around it (the weights sum to the mesh's area).

Problems with the file raise :class:`~shapeverify.errors.ScanError` naming it.

>>> import numpy as np
>>> v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
>>> t = np.array([[0, 1, 2], [0, 2, 3]])
>>> vertex_areas(v, t).tolist()
[0.3333333333333333, 0.16666666666666666, 0.3333333333333333, 0.16666666666666666]
"""

from __future__ import annotations

import numpy as np

from shapeverify.errors import CADImportError, EmptyModelError, ScanError

__all__ = ["read_mesh_scan", "sample_mesh", "vertex_areas", "MESH_SCAN_METHODS"]

MESH_SCAN_METHODS = ("sample", "vertices")
#: The most points ``sample`` draws (a mesh whose edges are tiny against its area is damaged).
MAX_SAMPLES = 50_000_000


def _areas(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)


def vertex_areas(vertices, triangles) -> np.ndarray:
    """(V,) the area each vertex stands for: a third of the area of every triangle using it
    (0 for unused vertices); the sum is the mesh's area."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    w = np.zeros(len(v))
    np.add.at(w, t.ravel(), np.repeat(_areas(v, t) / 3.0, 3))
    return w


def median_edge(vertices, triangles) -> float:
    """The median length of the triangles' edges (each edge counted once per triangle)."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    e = np.concatenate([v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 1]], v[t[:, 0]] - v[t[:, 2]]])
    return float(np.median(np.linalg.norm(e, axis=1)))


def sample_mesh(vertices, triangles, spacing: float | None = None, seed: int = 0) -> np.ndarray:
    """Points drawn uniformly on the triangles, one per ``sqrt(3)/2 * spacing**2`` of area on
    average (``spacing``: default the median edge length); (N, 3) float64.

    Raises
    ------
    ValueError
        ``spacing`` not positive, or more than :data:`MAX_SAMPLES` points asked for.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    s = median_edge(v, t) if spacing is None else float(spacing)
    area = _areas(v, t)
    if not (np.isfinite(s) and s > 0):
        raise ValueError(f"the sampling spacing must be a positive length, got {s!r} (a mesh "
                         "whose edges have zero median length is degenerate)")
    expected = area / (np.sqrt(3.0) / 2.0 * s * s)
    if expected.sum() > MAX_SAMPLES:
        raise ValueError(f"sampling the mesh at {s:.3g} would give {expected.sum():.3g} points "
                         f"(limit {MAX_SAMPLES:,}); give a larger spacing")
    rng = np.random.default_rng(seed)
    counts = np.floor(expected + rng.random(len(expected))).astype(np.int64)
    tri = np.repeat(np.arange(len(t)), counts)
    r1, r2 = rng.random(len(tri)), rng.random(len(tri))
    flip = r1 + r2 > 1.0                      # fold the unit square onto the triangle
    r1[flip], r2[flip] = 1.0 - r1[flip], 1.0 - r2[flip]
    a, b, c = v[t[tri, 0]], v[t[tri, 1]], v[t[tri, 2]]
    return a + r1[:, None] * (b - a) + r2[:, None] * (c - a)


def read_mesh_scan(path, method: str = "sample", spacing: float | None = None, seed: int = 0):
    """A mesh file read as a scan.

    Parameters
    ----------
    path : str or os.PathLike
        ``.stl``, ``.ply`` with faces, ``.obj`` (as :func:`shapeverify.io.mesh.read_mesh`).
    method : {"sample", "vertices"}
        See the module docstring.
    spacing : float, optional
        ``sample``: the spacing (mm); default the mesh's median edge length.
    seed : int
        ``sample``: the seed of the draw.

    Returns
    -------
    points : (N, 3) float64
        ``sample``: points on the triangles.  ``vertices``: the vertices used by a triangle.
    weights : (N,) float64
        ``sample``: the area each point stands for (all equal); ``vertices``: the vertex areas.
        Either way they sum to the mesh's area.

    Raises
    ------
    FileNotFoundError, UnsupportedFormatError
        As :func:`~shapeverify.io.mesh.read_mesh`.
    ScanError
        A damaged mesh file, one without triangles, or an unknown ``method``; names the file.
    """
    from shapeverify.io.mesh import read_mesh

    if method not in MESH_SCAN_METHODS:
        raise ScanError(f"{path}: unknown mesh-scan method {method!r}; use one of "
                        f"{', '.join(MESH_SCAN_METHODS)}")
    try:
        v, t = read_mesh(path)
    except (CADImportError, EmptyModelError) as exc:   # a broken scan, not a broken model
        raise ScanError(str(exc)) from None
    area = _areas(v, t)
    if not area.sum() > 0:
        raise ScanError(f"{path}: every triangle of the mesh has zero area")
    if method == "vertices":
        w = vertex_areas(v, t)
        used = np.zeros(len(v), bool)
        used[t.ravel()] = True
        return v[used], w[used]
    try:
        pts = sample_mesh(v, t, spacing, seed)
    except ValueError as exc:
        raise ScanError(f"{path}: {exc}") from None
    if len(pts) == 0:
        raise ScanError(f"{path}: the mesh is smaller than one sample at spacing "
                        f"{spacing if spacing is not None else median_edge(v, t):.3g}")
    return pts, np.full(len(pts), area.sum() / len(pts))
