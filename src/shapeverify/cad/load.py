"""``load_model``: read any supported reference-model file into a :class:`Model`.

Dispatch by extension (case-insensitive):

=====================================  ===========================================================
``.step .stp .igs .iges``              trimmed NURBS faces through OpenCASCADE
                                       (:func:`shapeverify.cad.occ_import.read_cad`), in mm
``.stl .obj``, ``.ply`` with faces     triangle mesh (``kind="mesh"``)
``.ply`` without faces, ``.xyz .txt``  point cloud (``kind="points"``); a PLY's ``nx ny nz``
``.csv .npy .pcd``                     become ``cloud_normals``
``.svmodel``                           a model saved by :meth:`Model.save` (no CAD import)
=====================================  ===========================================================

Meshes and point clouds carry no length unit: they are taken to be in millimetres
(``unit="mm"``, ``scale_to_mm=1``); scale them yourself if they are not.
"""

from __future__ import annotations

import errno
import logging
from pathlib import Path

import numpy as np

from shapeverify.errors import CADImportError, EmptyModelError, UnsupportedFormatError

__all__ = ["load_model", "MODEL_EXTENSIONS"]

logger = logging.getLogger(__name__)

_CAD = (".step", ".stp", ".igs", ".iges")
_MESH = (".stl", ".obj")
_CLOUD = (".xyz", ".txt", ".csv", ".npy", ".pcd")
_SAVED = (".svmodel",)
#: Every extension :func:`load_model` accepts.
MODEL_EXTENSIONS = _CAD + _MESH + (".ply",) + _CLOUD + _SAVED


def load_model(path):
    """Load a reference model (CAD, mesh, point cloud or saved model), in millimetres.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Model
        ``kind`` "cad" (one :class:`Face` per CAD face), "mesh" or "points".

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    UnsupportedFormatError
        The extension is not one of :data:`MODEL_EXTENSIONS` (the message lists them).
    CADImportError
        Corrupt, empty or truncated model file; OpenCASCADE raised or crashed on it (the import
        runs in a child process, so a crash never ends the caller); a damaged ``.svmodel`` gives
        its subclass :class:`~shapeverify.errors.ModelFileError`.
    EmptyModelError
        The file holds nothing to use (a CAD file without faces, a mesh without triangles).
    ScanError
        Corrupt or empty point-cloud file.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from shapeverify.io.points import write_ply
    >>> p = os.path.join(tempfile.mkdtemp(), "tri.ply")
    >>> _ = write_ply(p, np.eye(3), faces=[[0, 1, 2]])
    >>> load_model(p)  # doctest: +ELLIPSIS
    Model(kind='mesh', vertices=3, triangles=1, unit='mm', ...)
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in MODEL_EXTENSIONS:
        raise UnsupportedFormatError(
            f"{path}: unsupported model file extension {path.suffix or '(none)'!r}; supported: "
            f"{' '.join(MODEL_EXTENSIONS)}")
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, f"{path}: file not found", str(path))
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, f"{path}: is a directory, not a model file",
                                str(path))
    if not path.is_file():  # a pipe or a device: reading it would wait for ever
        raise CADImportError(f"{path}: is not a regular file (a pipe, socket or device); save "
                             "the model to a file and give that")
    if ext in _CAD:
        from shapeverify.cad.occ_import import read_cad

        model = read_cad(path)
        if len(model.faces) == 0:
            raise EmptyModelError(f"{path}: the CAD file holds no faces")
        return model
    if ext in _SAVED:
        from shapeverify.cad.persist import load_saved_model

        return load_saved_model(path)
    if ext in _MESH:
        from shapeverify.io.mesh import read_mesh

        return _mesh_model(path, *read_mesh(path))
    if ext == ".ply":
        return _ply_model(path)
    from shapeverify.io.points import read_points

    return _cloud_model(path, read_points(path), None)


def _mesh_model(path, vertices, triangles):
    from shapeverify.cad.model import Model

    logger.info("%s: mesh with %d vertices and %d triangles; no unit in the file, taken as mm",
                path, len(vertices), len(triangles))
    return Model(faces=(), unit="mm", scale_to_mm=1.0, source=str(path), kind="mesh",
                 vertices=vertices, triangles=triangles)


def _cloud_model(path, points, normals):
    from shapeverify.cad.model import Model

    logger.info("%s: point cloud with %d points%s; no unit in the file, taken as mm", path,
                len(points), " and normals" if normals is not None else "")
    return Model(faces=(), unit="mm", scale_to_mm=1.0, source=str(path), kind="points",
                 vertices=points, cloud_normals=normals)


def _ply_model(path):
    from shapeverify.io.points import drop_nonfinite, read_ply_full, valid_rows

    ply = read_ply_full(path)
    if ply.faces is not None and len(ply.faces):
        from shapeverify.io.mesh import check_vertices

        check_vertices(ply.vertices, path)
        return _mesh_model(path, ply.vertices, ply.faces.astype(np.int32))
    pts = ply.vertices
    normals = None
    if all(c in ply.properties for c in ("nx", "ny", "nz")):
        normals = np.column_stack([ply.properties[c].astype(np.float64)
                                   for c in ("nx", "ny", "nz")])
    ok = valid_rows(pts)             # the rows drop_nonfinite keeps
    pts = drop_nonfinite(pts, path)
    if normals is not None:
        normals = normals[ok]
        ln = np.linalg.norm(normals, axis=1)
        if not (np.isfinite(ln).all() and (ln > 0).all()):
            logger.warning("%s: some vertex normals are zero or not finite; normals ignored",
                           path)
            normals = None
        else:
            normals = normals / ln[:, None]
    return _cloud_model(path, pts, normals)
