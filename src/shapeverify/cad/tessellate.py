"""Triangle tessellation of trimmed NURBS faces (for ray seeds and for drawing the CAD surface).

The tessellation is only an approximation used to *seed* exact computations (ray intersection,
Newton on the NURBS surface) and to draw the model; exact answers never come from it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Tessellation:
    """Triangles of a model; vertices are not shared between faces.

    Attributes
    ----------
    vertices : (V, 3) float64, on the exact surface (mm)
    triangles : (T, 3) int64
    uv : (V, 2) float64, the (u, v) of each vertex on its face
    vertex_face : (V,) int64
    triangle_face : (T,) int64
    """

    vertices: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray
    vertex_face: np.ndarray
    triangle_face: np.ndarray

    def __repr__(self) -> str:
        return f"Tessellation(vertices={len(self.vertices):,}, triangles={len(self.triangles):,})"


def _grid_counts(surface, max_edge: float, max_per_side: int) -> tuple[np.ndarray, np.ndarray]:
    """Parameter values in u and v whose 3D spacing is about ``max_edge`` (by iso-line arc length)."""
    (u0, u1), (v0, v1) = surface.domain
    k = 17
    uu, vv = np.meshgrid(np.linspace(u0, u1, k), np.linspace(v0, v1, k), indexing="ij")
    pts = surface.evaluate(uu.ravel(), vv.ravel()).reshape(k, k, 3)
    len_u = np.linalg.norm(np.diff(pts, axis=0), axis=2).sum(axis=0).max()  # longest u iso-line
    len_v = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1).max()
    nu = int(np.clip(np.ceil(len_u / max_edge), 2, max_per_side)) + 1
    nv = int(np.clip(np.ceil(len_v / max_edge), 2, max_per_side)) + 1
    return np.linspace(u0, u1, nu), np.linspace(v0, v1, nv)


def tessellate_face(face, max_edge: float, max_per_side: int = 400, cover: bool = True):
    """Tessellate one trimmed face on a parameter grid, keeping triangles inside the trims.

    A triangle is kept when any of its three vertices or its centroid is inside the trimmed
    domain, or a trimming loop passes through its grid cell, so the tessellation covers the whole
    face (it overhangs the trims by up to one cell; exact computations check the trims again).
    With ``cover=False`` (for drawing) only triangles whose centroid is inside are kept.

    Returns
    -------
    vertices (V, 3), triangles (T, 3) int64, uv (V, 2)
    """
    us, vs = _grid_counts(face.surface, max_edge, max_per_side)
    nu, nv = len(us), len(vs)
    uu, vv = np.meshgrid(us, vs, indexing="ij")
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    b, c, d = a + nv, a + nv + 1, a + 1
    tris = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    centroids = uv[tris].mean(axis=1)
    keep = face.contains(centroids)
    if not cover:
        return _compact(face, uv, tris[keep])
    keep |= face.contains(uv)[tris].any(axis=1)
    # cells that a trimming loop passes through: a sliver of the face may lie in a cell whose
    # corners and centroids are all outside (a thin strip along a shared edge)
    cell = np.zeros((nu - 1, nv - 1), dtype=bool)
    for loop in face.loops:
        closed = np.vstack([loop, loop[:1]])
        seg = np.diff(closed, axis=0)
        cu, cv = (us[-1] - us[0]) / (nu - 1), (vs[-1] - vs[0]) / (nv - 1)
        steps = np.maximum(1, np.ceil(np.max(np.abs(seg) / [cu, cv], axis=1) * 2)).astype(int)
        pts = np.concatenate([closed[k] + seg[k] * np.linspace(0, 1, steps[k], endpoint=False)[:, None]
                              for k in range(len(seg))])
        iu = np.clip(np.searchsorted(us, pts[:, 0], side="right") - 1, 0, nu - 2)
        iv = np.clip(np.searchsorted(vs, pts[:, 1], side="right") - 1, 0, nv - 2)
        cell[iu, iv] = True
    keep |= np.concatenate([cell.ravel(), cell.ravel()])
    return _compact(face, uv, tris[keep])


def _compact(face, uv, tris):
    """Drop unused grid vertices and evaluate the rest on the exact surface."""
    if len(tris) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2))
    used = np.unique(tris)
    remap = np.full(len(uv), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    uv = uv[used]
    verts = face.surface.evaluate(uv[:, 0], uv[:, 1])
    return verts, remap[tris], uv


def tessellate_model(model, max_edge: float | None = None, max_per_side: int = 400,
                     cover: bool = True) -> Tessellation:
    """Tessellate every face of the part of a CAD model (or wrap a mesh model's triangles).

    Supplemental faces (``Model.supplemental``: geometry outside the part's solid) are left
    out: neither a camera nor the report sees surface the manufactured part does not have.

    Parameters
    ----------
    model : shapeverify.cad.model.Model
    max_edge : float, optional
        Target triangle edge length in mm (default: model size / 200).
    cover : bool
        True (seeds): cover every face completely, overhanging its trims; False (drawing): keep
        the triangles whose centroid lies inside the trims.

    Raises
    ------
    ValueError
        For a point-cloud model (nothing to tessellate) or a non-positive ``max_edge``.
    """
    if model.kind == "points":
        raise ValueError("a point-cloud model has no surface to tessellate; use a CAD or mesh model")
    if model.kind == "mesh":
        tris = np.asarray(model.triangles, dtype=np.int64)
        verts = np.asarray(model.vertices, dtype=np.float64)
        return Tessellation(verts, tris, np.zeros((len(verts), 2)), np.full(len(verts), -1, np.int64),
                            np.arange(len(tris), dtype=np.int64))
    if max_edge is None:
        max_edge = model.size / 200.0
    if not (max_edge > 0 and np.isfinite(max_edge)):
        raise ValueError(f"max_edge must be a positive length in mm, got {max_edge!r}")
    V, T, UV, VF, TF = [], [], [], [], []
    offset = 0
    part = model.part_faces() if hasattr(model, "part_faces") else range(len(model.faces))
    for f in part:  # supplemental geometry (Model.supplemental) is not the part
        face = model.faces[f]
        verts, tris, uv = tessellate_face(face, max_edge, max_per_side, cover)
        V.append(verts)
        T.append(tris + offset)
        UV.append(uv)
        VF.append(np.full(len(verts), f, np.int64))
        TF.append(np.full(len(tris), f, np.int64))
        offset += len(verts)
    return Tessellation(np.concatenate(V), np.concatenate(T), np.concatenate(UV),
                        np.concatenate(VF), np.concatenate(TF))
