"""The scan formats shapeverify reads: one registry, file suffix -> reader (as trimesh's ``exchange``).

Every reader takes the file's bytes and a ``name`` that stands for the data in error messages
(the path, an upload's description) and returns the ``(N, 3)`` float64 points as stored;
:func:`shapeverify.io.points.read_points` looks the reader up here and drops non-finite rows.
To read a new format, write such a function (in a module of its own under ``io/``) and add its
suffix to :data:`SCAN_READERS`; :data:`SCAN_SUFFIXES` (what the CLI, batch and the error
messages list) follows.

A scan source is a path, the file's bytes (``bytes``, ``bytearray``, ``memoryview``) or a binary
file object (``open(path, "rb")``, ``io.BytesIO``); :func:`source_bytes` turns any of them into
``(data, name)``.

Example
-------
>>> from shapeverify.io.formats import SCAN_SUFFIXES, scan_reader
>>> SCAN_SUFFIXES
('.ply', '.xyz', '.txt', '.csv', '.npy', '.pcd')
>>> scan_reader("XYZ").__name__
'read_table'
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Callable

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError
from shapeverify.io.npy import read_npy
from shapeverify.io.pcd import read_pcd
from shapeverify.io.ply import read_ply_points
from shapeverify.io.tables import read_table

__all__ = ["SCAN_READERS", "SCAN_SUFFIXES", "scan_reader", "source_bytes", "source_suffix",
           "check_file"]

#: file suffix (lower case, with the dot) -> reader ``(data: bytes, name: str) -> (N, 3) array``
SCAN_READERS: dict[str, Callable[[bytes, str], np.ndarray]] = {
    ".ply": read_ply_points,
    ".xyz": read_table,
    ".txt": read_table,
    ".csv": read_table,
    ".npy": read_npy,
    ".pcd": read_pcd,
}
#: The suffixes of the scan files shapeverify reads (the one list).
SCAN_SUFFIXES = tuple(SCAN_READERS)


def scan_reader(fmt: str, name: str | None = None) -> Callable[[bytes, str], np.ndarray]:
    """The reader of format ``fmt``: a suffix with or without the dot, any case (``"ply"``,
    ``".PLY"``).

    Raises
    ------
    UnsupportedFormatError
        ``fmt`` is not one of :data:`SCAN_SUFFIXES` (the message lists them).
    """
    key = str(fmt).strip().lower()
    key = key if key.startswith(".") else "." + key
    reader = SCAN_READERS.get(key)
    if reader is None:
        where = f"{name}: " if name else ""
        raise UnsupportedFormatError(f"{where}unsupported point-cloud extension {fmt!r}; "
                                     f"supported: {', '.join(SCAN_SUFFIXES)}")
    return reader


def _is_path(source) -> bool:
    return isinstance(source, (str, os.PathLike))


def check_file(path) -> Path:
    """``path`` as a Path after checking that it is a non-empty file.

    Raises
    ------
    FileNotFoundError
        It does not exist.
    ScanError
        It is a directory or empty.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, f"{path}: file not found", str(path))
    if path.is_dir():
        raise ScanError(f"{path}: is a directory, not a file")
    if path.stat().st_size == 0:
        raise ScanError(f"{path}: file is empty (0 bytes)")
    return path


def source_suffix(source) -> str | None:
    """The suffix a source's name carries (a path's, a file object's ``name``), else None."""
    if _is_path(source):
        return Path(source).suffix
    fname = getattr(source, "name", None)
    return Path(fname).suffix if isinstance(fname, (str, os.PathLike)) else None


def source_bytes(source, name: str | None = None) -> tuple[bytes, str]:
    """The bytes of a scan source and the name that stands for it in messages.

    Parameters
    ----------
    source : str, os.PathLike, bytes, bytearray, memoryview or binary file object
    name : str, optional
        Default: the path, the file object's ``name``, or ``"<bytes>"``.

    Returns
    -------
    data : bytes
    name : str

    Raises
    ------
    FileNotFoundError
        A path that does not exist.
    ScanError
        A directory, or no data (0 bytes).
    TypeError
        Anything else than the sources above (a text-mode file object included).
    """
    if _is_path(source):
        path = check_file(source)
        return path.read_bytes(), str(path) if name is None else name
    if isinstance(source, (bytes, bytearray, memoryview)):
        data, default = bytes(source), "<bytes>"
    elif callable(getattr(source, "read", None)):
        data = source.read()
        if not isinstance(data, (bytes, bytearray)):
            raise TypeError(f"a scan file object must be opened in binary mode ('rb'), got "
                            f"{type(data).__name__} from {type(source).__name__}.read()")
        data = bytes(data)
        fname = getattr(source, "name", None)
        default = str(fname) if isinstance(fname, (str, os.PathLike)) else "<file object>"
    else:
        raise TypeError(f"a scan source is a path, bytes or a binary file object, got "
                        f"{type(source).__name__}")
    name = default if name is None else name
    if not data:
        raise ScanError(f"{name}: is empty (0 bytes)")
    return data, name
