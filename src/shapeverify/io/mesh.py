"""Read triangle meshes (``.stl`` ascii/binary, ``.ply`` with faces, ``.obj``).

All readers return ``(vertices (V, 3) float64, triangles (T, 3) int32)``.  Polygons are
triangulated as fans ``(p0, pi, pi+1)``.  STL stores a triangle soup; exactly coincident vertices
are merged so that the mesh is connected (needed to find its free edges).  A mesh is a reference
model, so problems raise :class:`~shapeverify.errors.CADImportError` (corrupt file),
:class:`~shapeverify.errors.EmptyModelError` (no triangles) or
:class:`~shapeverify.errors.UnsupportedFormatError` (unknown extension), with the file name
and what is wrong.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from shapeverify.errors import CADImportError, EmptyModelError, ScanError, UnsupportedFormatError
from shapeverify.io.formats import check_file as _check_file
from shapeverify.io.ply import read_ply_full

__all__ = ["read_mesh", "check_vertices", "MESH_EXTENSIONS"]

logger = logging.getLogger(__name__)

#: File extensions :func:`read_mesh` understands.
MESH_EXTENSIONS = (".stl", ".ply", ".obj")


def read_mesh(path):
    """Read a triangle mesh.

    Parameters
    ----------
    path : str or os.PathLike
        ``.stl`` (ascii or binary), ``.ply`` with a face element, ``.obj`` (``v`` and ``f`` lines;
        ``f`` entries as ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``; negative indices count back
        from the last vertex defined so far).

    Returns
    -------
    vertices : (V, 3) float64
    triangles : (T, 3) int32
        Indices into ``vertices``.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    UnsupportedFormatError
        Unknown extension.
    CADImportError
        Empty (0 bytes), truncated or malformed file; non-finite vertex coordinates; indices
        out of range.
    EmptyModelError
        The file holds no triangles (e.g. a PLY point cloud).
    """
    try:
        path = _check_file(path)
    except ScanError as exc:  # empty file: a broken model file, not a broken scan
        raise CADImportError(str(exc)) from None
    ext = path.suffix.lower()
    try:
        v, t = _read_any(path, ext)
    except (CADImportError, EmptyModelError) as exc:  # content of another format: say which
        from shapeverify.io.formats import suffix_hint

        with open(path, "rb") as fh:
            hint = suffix_hint(fh.read(4096), ext)
        if hint and hint not in str(exc):
            raise type(exc)(f"{exc}{hint}") from None
        raise
    if len(t) == 0:
        raise EmptyModelError(f"{path}: mesh has no triangles")
    check_vertices(v, path)
    return np.ascontiguousarray(v, dtype=np.float64), np.ascontiguousarray(t, dtype=np.int32)


def _read_any(path: Path, ext: str):
    """(vertices, triangles) of the mesh file ``path`` by its extension ``ext``."""
    if ext == ".stl":
        return _read_stl(path)
    if ext == ".ply":
        try:
            ply = read_ply_full(path)
        except ScanError as exc:
            raise CADImportError(str(exc)) from None
        if ply.faces is None or len(ply.faces) == 0:
            raise EmptyModelError(f"{path}: PLY file has no faces (a point cloud, not a mesh)")
        return ply.vertices, ply.faces
    if ext == ".obj":
        return _read_obj(path)
    raise UnsupportedFormatError(f"{path}: unsupported mesh extension {path.suffix!r}; "
                                 f"supported: {', '.join(MESH_EXTENSIONS)}")


def check_vertices(vertices: np.ndarray, path) -> None:
    """Refuse mesh vertices with NaN/inf coordinates or coordinates beyond
    :data:`shapeverify.io.points.MAX_COORDINATE` (a mesh cannot drop vertices as a scan drops
    rows: its triangles index them).

    Raises
    ------
    CADImportError
        The message counts the bad vertices and names the file.
    """
    from shapeverify.io.points import MAX_COORDINATE

    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices).all(axis=1)).sum())
        raise CADImportError(f"{path}: {bad} mesh vertices have NaN or infinite coordinates")
    huge = (np.abs(vertices) > MAX_COORDINATE).any(axis=1)
    if huge.any():
        raise CADImportError(f"{path}: {int(huge.sum())} mesh vertices have coordinates beyond "
                             f"+-{MAX_COORDINATE:g} (up to {float(np.abs(vertices).max()):.3g}): "
                             "not a part in any length unit; the file is damaged")


# ---------------------------------------------------------------------------------------- STL
_STL_REC = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _read_stl(path: Path):
    data = path.read_bytes()
    n_bin = int(np.frombuffer(data, "<u4", 1, 80)[0]) if len(data) >= 84 else -1
    is_binary = n_bin >= 0 and len(data) == 84 + 50 * n_bin
    if not is_binary and data.lstrip()[:5].lower() != b"solid":
        tail = data[84 + 50 * n_bin:] if n_bin >= 0 else b""
        if n_bin > 0 and tail and len(tail) < 50 and not tail.strip(b"\0 \t\r\n"):
            is_binary = True  # padding (zeros, a newline) after a valid binary body
        elif n_bin > 0 and len(data) > 84 + 50 * n_bin:
            raise CADImportError(
                f"{path}: the binary STL header declares {n_bin} triangles "
                f"({84 + 50 * n_bin} bytes), the file has {len(data)} bytes: data was inserted "
                "or appended, or the count is wrong; export the mesh again")
        else:
            raise CADImportError(f"{path}: not an STL file (neither 'solid ...' text nor a binary "
                            f"STL of consistent size: header says {max(n_bin, 0)} triangles, "
                            f"file has {len(data)} bytes)")
    if is_binary:
        rec = np.frombuffer(data, _STL_REC, n_bin, 84)
        corners = rec["v"].reshape(-1, 3).astype(np.float64)
    else:
        tok = np.array(data.split())
        idx = np.flatnonzero(tok == b"vertex")
        if idx.size == 0:
            raise CADImportError(f"{path}: ascii STL without any 'vertex' line")
        if idx.size % 3:
            raise CADImportError(f"{path}: ascii STL has {idx.size} vertices, not a multiple of 3")
        if idx[-1] + 3 >= tok.size:
            raise CADImportError(f"{path}: truncated ascii STL")
        try:
            corners = tok[(idx[:, None] + np.arange(1, 4))].astype(np.float64)
        except ValueError:
            raise CADImportError(f"{path}: malformed ascii STL: a 'vertex' line without three "
                            "numbers") from None
    return _merge_soup(corners)


def _merge_soup(corners: np.ndarray):
    """Triangle soup (3T, 3) -> shared vertices (exactly equal coordinates merged)."""
    if len(corners) == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int32)
    verts, inv = np.unique(corners, axis=0, return_inverse=True)
    return verts, inv.reshape(-1, 3).astype(np.int32)


# ---------------------------------------------------------------------------------------- OBJ
def _read_obj(path: Path):
    verts: list[list[float]] = []
    tris: list[tuple[int, int, int]] = []
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        for lineno, line in enumerate(fh, start=1):
            if line.startswith("v "):
                tok = line.split()
                try:
                    verts.append([float(tok[1]), float(tok[2]), float(tok[3])])
                except (IndexError, ValueError):
                    raise CADImportError(f"{path}:{lineno}: malformed vertex line "
                                    f"{line.strip()[:80]!r} (need 'v x y z')") from None
            elif line.startswith("f "):
                tok = line.split()[1:]
                if len(tok) < 3:
                    raise CADImportError(f"{path}:{lineno}: face with fewer than 3 vertices")
                nv = len(verts)
                try:
                    ids = [int(t.split("/", 1)[0]) for t in tok]
                except ValueError:
                    raise CADImportError(f"{path}:{lineno}: malformed face line "
                                    f"{line.strip()[:80]!r}") from None
                ids = [i - 1 if i > 0 else nv + i for i in ids]
                if any(i < 0 or i >= nv or j == 0 for i, j in
                       zip(ids, (int(t.split('/', 1)[0]) for t in tok))):
                    raise CADImportError(f"{path}:{lineno}: face index out of range "
                                    f"(1..{nv} or -1..-{nv}): {line.strip()[:80]!r}")
                for k in range(1, len(ids) - 1):
                    tris.append((ids[0], ids[k], ids[k + 1]))
    if not verts:
        raise CADImportError(f"{path}: OBJ file has no vertices ('v' lines)")
    if not tris:
        raise EmptyModelError(f"{path}: OBJ file has no faces ('f' lines)")
    return np.array(verts, dtype=np.float64), np.array(tris, dtype=np.int32)
