"""Mesh scans: the ``.stl`` and ``.obj`` files many structured-light scanners deliver.

A scanner's mesh puts its measured points at the vertices, so the scan points are **the mesh's
vertices** (an STL's coincident copies merged, as :func:`shapeverify.io.mesh.read_mesh` merges
them) **plus points on the triangles that are larger than the mesh's own resolution**: a mesh
that was decimated where the surface is flat has a few large triangles there, and the
inspection's support and coverage rules count points per area. A triangle of area A gets the
interior points of a barycentric lattice of step ``1/m``, ``m = floor(sqrt(A / A_median))``
(none for ``m < 3``), so every part of the surface carries about the median triangle's density.
On a mesh of even triangles that adds nothing: the points are exactly the vertices.

(A PLY file with faces is read by the PLY reader: its vertices, as before.)

Example
-------
>>> import numpy as np
>>> from shapeverify.io.mesh_scan import mesh_scan_points
>>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.]])
>>> mesh_scan_points(v, np.array([[0, 1, 2], [1, 3, 2]])).shape   # even triangles: the vertices
(4, 3)
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from shapeverify.errors import CADImportError, EmptyModelError, ScanError

__all__ = ["read_stl_scan", "read_obj_scan", "mesh_scan_points"]

#: a triangle gets at most this many lattice steps per edge (m**2 / 2 interior points)
_MAX_STEPS = 64


def mesh_scan_points(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The scan points of a mesh: its vertices, then interior lattice points of the triangles
    larger than its resolution (see the module docstring), (N, 3) float64."""
    vertices = np.asarray(vertices, np.float64)
    tri = vertices[np.asarray(triangles)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ok = area > 0
    if not ok.any():
        return vertices
    ref = float(np.median(area[ok]))
    m = np.minimum(np.floor(np.sqrt(area / ref)), _MAX_STEPS).astype(int)
    extra = []
    for steps in np.unique(m[m >= 3]):
        i, j = np.meshgrid(np.arange(1, steps), np.arange(1, steps), indexing="ij")
        keep = (i + j) < steps
        bary = np.column_stack([i[keep], j[keep], steps - i[keep] - j[keep]]) / steps
        extra.append(np.einsum("pk,tkc->tpc", bary, tri[m == steps]).reshape(-1, 3))
    return np.concatenate([vertices, *extra]) if extra else vertices


def _read(data: bytes, name: str, ext: str) -> np.ndarray:
    from shapeverify.io.mesh import read_mesh

    with tempfile.TemporaryDirectory() as tmp:   # the mesh readers read files
        path = os.path.join(tmp, "scan" + ext)
        with open(path, "wb") as fh:
            fh.write(data)
        try:
            vertices, triangles = read_mesh(path)
        except (CADImportError, EmptyModelError) as exc:
            raise ScanError(str(exc).replace(path, name)) from None
    return mesh_scan_points(vertices, triangles)


def read_stl_scan(data: bytes, name: str) -> np.ndarray:
    """The scan points of an ``.stl`` file's bytes (ascii or binary): :func:`mesh_scan_points`."""
    return _read(data, name, ".stl")


def read_obj_scan(data: bytes, name: str) -> np.ndarray:
    """The scan points of an ``.obj`` file's bytes: :func:`mesh_scan_points`."""
    return _read(data, name, ".obj")
