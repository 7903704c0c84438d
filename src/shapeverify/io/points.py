"""Read scans and point clouds (from a path, bytes or a binary file object); write PLY files.

Formats read by :func:`read_points` (dispatch by file extension, case-insensitive, through the
registry :mod:`shapeverify.io.formats`; the parsers live in :mod:`.ply`, :mod:`.tables`,
:mod:`.npy`, :mod:`.pcd`):

``.ply``
    ascii, binary_little_endian and binary_big_endian; the ``x y z`` properties of element
    ``vertex`` (any numeric type).  Other properties and elements (faces, range grids) are
    skipped.
``.xyz`` ``.txt`` ``.csv``
    one point per line, separated by whitespace, ``,`` or ``;``; an optional header line; ``#``
    comments; the first three columns are ``x y z``, further columns are ignored.
``.npy``
    an ``(N, 3)`` or ``(N, >=3)`` numeric array (first three columns), or a structured array
    with fields ``x y z``.  Loaded without pickle.
``.pcd``
    Point Cloud Library files with ``DATA ascii``, ``binary`` or ``binary_compressed`` (LZF)
    and fields ``x y z``.
``.e57``
    ASTM E57 (:mod:`.e57`): every scan of the file with its pose applied, in the file's common
    frame, converted from the standard's metres to mm (:func:`shapeverify.io.e57.read_e57_views`
    gives the scans one by one).  Needs the ``scanners`` extra (pye57).
``.las`` ``.laz``
    ASPRS LAS/LAZ (:mod:`.las`): scale and offset applied, in the file's unit.  Needs the
    ``scanners`` extra (laspy; LAZ also a backend: ``laspy[lazrs]``).

Every reader checks the counts its header declares against the data: more or less data than
declared (rows appended, bytes inserted, a truncated file) is a ScanError that gives both
numbers, never a silently truncated or shifted cloud.

Rows with a NaN or infinite coordinate, or one beyond +-1e12 (:data:`MAX_COORDINATE`: no length
unit makes that a measurement; it is what garbage bytes decode to), are dropped; the number
dropped is logged as a warning with the file name.  Empty or malformed files raise :class:`~shapeverify.errors.ScanError` (or
:class:`~shapeverify.errors.UnsupportedFormatError` for an unknown extension) whose message starts
with the file name and says what is wrong.  Units are whatever the file holds (the library works
in millimetres; converting a scanner's metres is the caller's business).
"""

from __future__ import annotations

import logging
import os

import numpy as np

from .._arrays import count_nonfinite_rows

from shapeverify.errors import ScanError
from shapeverify.io.formats import (SCAN_SUFFIXES, check_file, scan_reader, source_bytes,
                                    source_suffix, suffix_hint)
from shapeverify.io.ply import PlyData, ply_bytes, read_ply_full, write_ply
from shapeverify.io.formats import load_readers

load_readers()       # the registry's readers, imported with this module (as before it was lazy)

__all__ = ["read_points", "read_ply_full", "write_ply", "ply_bytes", "PlyData", "POINT_EXTENSIONS",
           "drop_nonfinite", "valid_rows", "MAX_COORDINATE"]

logger = logging.getLogger(__name__)

#: File extensions :func:`read_points` understands (the registry's list).
POINT_EXTENSIONS = SCAN_SUFFIXES
#: Largest coordinate magnitude read as a measurement (in any unit: 1e12 mm is a million km);
#: rows beyond it are dropped like NaN rows.
MAX_COORDINATE = 1e12
_check_file = check_file  # the name io.mesh and older code import


def read_points(source, format: str | None = None, *, name: str | None = None) -> np.ndarray:
    """Read a scan / point cloud into an ``(N, 3)`` float64 array.

    Parameters
    ----------
    source : str, os.PathLike, bytes or binary file object
        A ``.ply``, ``.xyz``, ``.txt``, ``.csv``, ``.npy`` or ``.pcd`` file (see the module
        docstring), its bytes, or a file object opened with ``"rb"``.
    format : str, optional
        The format as a suffix (``".ply"`` or ``"ply"``); needed for bytes, and for a file
        object without a ``name``; default: the path's (or the file object's name's) suffix.
    name : str, optional
        Stands for the data in error messages (default: the path, or the file object's name).

    Returns
    -------
    points : (N, 3) float64
        Finite points, in file order (rows with NaN/inf removed, count logged).

    Raises
    ------
    UnsupportedFormatError
        Unknown extension.
    FileNotFoundError
        The file does not exist.
    ScanError
        Empty, truncated or malformed file; no ``x y z``; fewer than three columns;
        no finite point.
    ValueError
        Bytes (or a file object without a name) and no ``format``.

    Examples
    --------
    >>> import io, numpy as np, tempfile, os
    >>> from shapeverify.io.points import ply_bytes, read_points, write_ply
    >>> p = os.path.join(tempfile.mkdtemp(), "a.ply")
    >>> _ = write_ply(p, np.eye(3))
    >>> read_points(p).shape
    (3, 3)
    >>> data = ply_bytes(np.eye(3))
    >>> bool((read_points(data, "ply") == read_points(io.BytesIO(data), ".ply")).all())
    True
    """
    fmt = source_suffix(source) if format is None else format
    if isinstance(source, (str, os.PathLike)):
        path = check_file(source)  # a missing file is named before its extension is judged
        name = str(path) if name is None else name
        reader = scan_reader(fmt, name)
        data = path.read_bytes()
    else:
        data, name = source_bytes(source, name)
        if fmt is None:
            raise ValueError(f"{name}: give the format of the scan data (format='.ply', one of "
                             f"{', '.join(SCAN_SUFFIXES)})")
        reader = scan_reader(fmt, name)
    try:
        points = reader(data, name)
    except ScanError as exc:  # a file named for another format: say which suffix fits
        hint = suffix_hint(data, fmt)
        if hint:
            raise type(exc)(f"{exc}{hint}") from None
        raise
    return drop_nonfinite(points, name)


def valid_rows(points: np.ndarray) -> np.ndarray:
    """(N,) bool: the rows :func:`drop_nonfinite` keeps (finite, within :data:`MAX_COORDINATE`)."""
    with np.errstate(invalid="ignore"):
        return (np.abs(points) <= MAX_COORDINATE).all(axis=1)


def drop_nonfinite(points: np.ndarray, path) -> np.ndarray:
    """Drop rows with a NaN/inf coordinate or one beyond :data:`MAX_COORDINATE` (logging their
    count); error if nothing is left."""
    n_bad = count_nonfinite_rows(points) if points.ndim == 2 else 0
    if len(points) == 0:
        raise ScanError(f"{path}: contains no points")
    if n_bad:
        logger.warning("%s: dropped %d of %d rows with NaN or infinite coordinates",
                       path, n_bad, len(points))
        points = points[np.isfinite(points).all(axis=1)]
        if len(points) == 0:
            raise ScanError(f"{path}: all {n_bad} points have NaN or infinite coordinates")
    if points.ndim == 2 and len(points):
        huge = (np.abs(points) > MAX_COORDINATE).any(axis=1)
        n_huge = int(np.count_nonzero(huge))
        if n_huge == len(points):
            raise ScanError(f"{path}: all {n_huge} points have coordinates beyond "
                            f"+-{MAX_COORDINATE:g} (up to {float(np.abs(points).max()):.3g}): "
                            "not a measurement in any length unit; the file is damaged or its "
                            "columns are not x y z")
        if n_huge:
            logger.warning("%s: dropped %d of %d rows with coordinates beyond +-%g (garbage "
                           "values, not measurements)", path, n_huge, len(points), MAX_COORDINATE)
            points = points[~huge]
    return np.ascontiguousarray(points, dtype=np.float64)
