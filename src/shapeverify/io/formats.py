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
('.ply', '.xyz', '.txt', '.csv', '.npy', '.pcd', '.e57', '.las', '.laz', '.stl', '.obj')
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
from shapeverify.io.e57 import read_e57
from shapeverify.io.las import read_las
from shapeverify.io.mesh_scan import read_obj_scan, read_stl_scan
from shapeverify.io.npy import read_npy
from shapeverify.io.pcd import read_pcd
from shapeverify.io.ply import read_ply_points
from shapeverify.io.tables import read_table

__all__ = ["SCAN_READERS", "SCAN_SUFFIXES", "scan_reader", "source_bytes", "source_suffix",
           "check_file", "sniff_format", "suffix_hint"]

#: file suffix (lower case, with the dot) -> reader ``(data: bytes, name: str) -> (N, 3) array``
SCAN_READERS: dict[str, Callable[[bytes, str], np.ndarray]] = {
    ".ply": read_ply_points,
    ".xyz": read_table,
    ".txt": read_table,
    ".csv": read_table,
    ".npy": read_npy,
    ".pcd": read_pcd,
    ".e57": read_e57,   # all scans of the file, in its common frame, mm (the scanners extra)
    ".las": read_las,   # as stored (the scanners extra)
    ".laz": read_las,
    ".stl": read_stl_scan,   # a scanner's mesh: its vertices (+ points on large triangles)
    ".obj": read_obj_scan,
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
        It is a directory, a pipe, socket or device, or empty.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, f"{path}: file not found", str(path))
    if path.is_dir():
        raise ScanError(f"{path}: is a directory, not a file")
    if not path.is_file():   # reading a pipe or a device would wait or never end
        raise ScanError(f"{path}: is not a regular file (a pipe, socket or device); save the "
                        "data to a file and give that")
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


# the file families a content sniff can tell apart: suffix -> family
_FAMILY = {".ply": "PLY", ".npy": "NumPy .npy", ".pcd": "PCD", ".step": "STEP", ".stp": "STEP",
           ".igs": "IGES", ".iges": "IGES", ".stl": "STL", ".obj": "OBJ", ".xyz": "text",
           ".txt": "text", ".csv": "text", ".e57": "E57", ".las": "LAS", ".laz": "LAS"}
_SUFFIX = {"PLY": ".ply", "NumPy .npy": ".npy", "PCD": ".pcd", "STEP": ".step", "IGES": ".igs",
           "STL": ".stl", "OBJ": ".obj", "E57": ".e57", "LAS": ".las"}


def sniff_format(data: bytes) -> str | None:
    """What a file's first bytes say it is: ``"PLY"``, ``"NumPy .npy"``, ``"PCD"``, ``"STEP"``,
    ``"IGES"``, ``"STL"``, ``"OBJ"``, ``"E57"``, ``"LAS"``, or None (plain text tables and unknown content).

    Only for messages: the readers never guess a format from the content.

    >>> sniff_format(b"ply\\nformat ascii 1.0\\n"), sniff_format(b"1 2 3\\n")
    ('PLY', None)
    """
    head = bytes(data[:4096])
    if head.startswith((b"ply\n", b"ply\r", b"ply ")):
        return "PLY"
    if head.startswith(b"\x93NUMPY"):
        return "NumPy .npy"
    if head.startswith(b"ASTM-E57"):
        return "E57"
    if head.startswith(b"LASF"):
        return "LAS"
    text = head.lstrip()
    if text.startswith(b"ISO-10303-21"):
        return "STEP"
    if len(head) >= 80 and head[72:73] == b"S" and head[73:80].strip().isdigit():
        return "IGES"
    if text.startswith(b"# .PCD") or (b"\nFIELDS " in head and b"\nDATA " in head):
        return "PCD"
    if text[:5].lower() == b"solid" and b"facet" in head:
        return "STL"
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", 1, 80)[0])
        if len(data) == 84 + 50 * n and n > 0:
            return "STL"
    if b"\0" not in head and (head.startswith(b"v ") or b"\nv " in head) and b"\nf " in head:
        return "OBJ"
    return None


def suffix_hint(data: bytes, suffix: str | None) -> str:
    """``"; the content looks like a PLY file: give it the suffix .ply"`` when the content's
    format (:func:`sniff_format`) is not the one its suffix names, else ``""``."""
    seems = sniff_format(data)
    key = str(suffix or "").strip().lower()
    key = key if key.startswith(".") or not key else "." + key   # "ply" as format= gives it
    if seems is None or _FAMILY.get(key) == seems:
        return ""
    article = "an" if seems in ("STL", "IGES", "OBJ") else "a"
    return f"; the content looks like {article} {seems} file: give it the suffix {_SUFFIX[seems]}"
