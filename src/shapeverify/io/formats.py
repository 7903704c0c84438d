"""The scan formats shapeverify reads: one registry of :class:`ScanFormat` (as trimesh's ``exchange``).

Each format is one :class:`ScanFormat` row of :data:`SCAN_FORMATS`: its file suffix, its reader,
the HTTP content types that name it, the first bytes that identify it and the unit its file
stores.  Every reader takes the file's bytes and a ``name`` that stands for the data in error
messages (the path, an upload's description) and returns the ``(N, 3)`` float64 points in mm;
:func:`shapeverify.io.points.read_points` looks the reader up here and drops non-finite rows.
Everything else follows from the registry: :data:`SCAN_SUFFIXES` (what the CLI's help, batch
and the error messages list), :func:`sniff_format` / :func:`sniff_scan` (content sniffing), the
service's content types, its sniffing and its 415 text (:mod:`shapeverify.service.body`).

To read a new format: write the reader (a module of its own under ``io/``) and add one
:class:`ScanFormat` row to :data:`SCAN_FORMATS` (``tests/test_scan_formats.py`` then
round-trips it: give it a writer there).

The module imports no reader and no numpy until a reader is used (the CLI builds its help from
it).

A scan source is a path, the file's bytes (``bytes``, ``bytearray``, ``memoryview``) or a binary
file object (``open(path, "rb")``, ``io.BytesIO``); :func:`source_bytes` turns any of them into
``(data, name)``.

Example
-------
>>> from shapeverify.io.formats import SCAN_SUFFIXES, scan_reader, scan_format
>>> SCAN_SUFFIXES
('.ply', '.xyz', '.txt', '.csv', '.npy', '.pcd', '.e57', '.las', '.laz', '.stl', '.obj')
>>> scan_reader("XYZ").__name__
'read_table'
>>> scan_format(".e57").unit, scan_format("las").content_types
('m', ('application/vnd.las',))
"""

from __future__ import annotations

import errno
import importlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Union

from shapeverify.errors import ScanError, UnsupportedFormatError

__all__ = ["ScanFormat", "SCAN_FORMATS", "SCAN_READERS", "SCAN_SUFFIXES", "scan_format",
           "scan_reader", "source_bytes", "source_suffix", "check_file", "sniff_format",
           "sniff_scan", "suffix_hint", "scan_help", "scan_families", "load_readers", "SCAN_CONTENT_TYPES"]

#: a file's first bytes -> does it look like this format?
Magic = Union[tuple, Callable[[bytes], bool]]


@dataclass(frozen=True)
class ScanFormat:
    """One scan format of the registry.

    Parameters
    ----------
    suffix : str
        File suffix, lower case with the dot (``".ply"``).
    reader : str or callable
        ``(data: bytes, name: str) -> (N, 3) float64`` points in mm, or its ``"module:function"``
        (imported at first use: the CLI reads the registry without importing numpy).
    content_types : tuple of str
        HTTP content types that name the format (the service reads a body sent with one of
        them in this format).
    magic : tuple of bytes, or callable
        First bytes that identify the content (any of the prefixes, after leading white space
        for text formats), or a test ``head -> bool`` on the first 4 KiB (the whole data for
        binary STL, whose size identifies it); ``()`` for formats that content cannot tell
        (plain text tables).
    unit : str
        Unit of the file's coordinates: ``"mm"`` (files without a unit are read as mm) or the
        unit the format fixes (``"m"`` for E57; its reader converts to mm).
    family : str
        What :func:`sniff_format` calls the content (``"PLY"``); formats of one family share
        their magic (``.las``/``.laz``, the text tables).
    """

    suffix: str
    reader: Union[str, Callable]
    content_types: tuple = ()
    magic: Magic = ()
    unit: str = "mm"
    family: str = ""

    def read(self, data: bytes, name: str):
        """The points of ``data`` (this format's reader)."""
        return self.load()(data, name)

    def load(self) -> Callable:
        """The reader function (imported on first use, then kept)."""
        if callable(self.reader):
            return self.reader
        fn = _LOADED.get(self.reader)
        if fn is None:
            module, _, attr = self.reader.partition(":")
            fn = _LOADED[self.reader] = getattr(importlib.import_module(module), attr)
        return fn

    def matches(self, data: bytes) -> bool:
        """Do the first bytes of ``data`` identify this format?"""
        if callable(self.magic):
            return bool(self.magic(data))
        head = bytes(data[:4096])
        return bool(self.magic) and (head.startswith(self.magic)
                                     or head.lstrip().startswith(self.magic))


#: "module:function" -> the reader, once imported
_LOADED: dict[str, Callable] = {}


def load_readers() -> None:
    """Import every registered reader now (:mod:`shapeverify.io.points` does, at its import:
    a first read then allocates nothing for imports)."""
    for f in SCAN_FORMATS:
        f.load()


def _pcd(data: bytes) -> bool:
    head = bytes(data[:4096])
    return head.lstrip().startswith((b"# .PCD", b"VERSION", b"FIELDS")) or \
        (b"\nFIELDS " in head and b"\nDATA " in head)


def _stl(data: bytes) -> bool:
    head = bytes(data[:4096])
    if head.lstrip()[:5].lower() == b"solid" and b"facet" in head:
        return True
    if len(data) >= 84:            # binary: 80-byte header, count, 50 bytes per triangle
        n = int.from_bytes(bytes(data[80:84]), "little")
        return n > 0 and len(data) == 84 + 50 * n
    return False


def _obj(data: bytes) -> bool:
    head = bytes(data[:4096])
    return b"\0" not in head and (head.startswith(b"v ") or b"\nv " in head) and b"\nf " in head


_TEXT = ()     # plain text tables: no magic (the service tells them from their numbers)
#: The registry: one row per scan format, in the order the CLI and the messages list them.
SCAN_FORMATS: tuple[ScanFormat, ...] = (
    ScanFormat(".ply", "shapeverify.io.ply:read_ply_points",
               ("application/ply", "model/ply", "application/x-ply"),
               (b"ply\n", b"ply\r", b"ply "), family="PLY"),
    ScanFormat(".xyz", "shapeverify.io.tables:read_table", ("text/x-xyz",), _TEXT,
               family="text"),
    ScanFormat(".txt", "shapeverify.io.tables:read_table", (), _TEXT, family="text"),
    ScanFormat(".csv", "shapeverify.io.tables:read_table", ("text/csv",), _TEXT, family="text"),
    ScanFormat(".npy", "shapeverify.io.npy:read_npy", ("application/x-npy", "application/npy"),
               (b"\x93NUMPY",), family="NumPy .npy"),
    ScanFormat(".pcd", "shapeverify.io.pcd:read_pcd", ("application/x-pcd",), _pcd,
               family="PCD"),
    # all scans of the file, in its common frame (the scanners extra)
    ScanFormat(".e57", "shapeverify.io.e57:read_e57", ("application/x-e57",), (b"ASTM-E57",),
               unit="m", family="E57"),
    # as stored (the scanners extra); LAS and LAZ: laspy tells them apart from the header
    ScanFormat(".las", "shapeverify.io.las:read_las", ("application/vnd.las",), (b"LASF",),
               family="LAS"),
    ScanFormat(".laz", "shapeverify.io.las:read_las", ("application/vnd.laszip",), (b"LASF",),
               family="LAS"),
    # a scanner's mesh: its vertices (+ points on large triangles)
    ScanFormat(".stl", "shapeverify.io.mesh_scan:read_stl_scan", ("model/stl", "application/sla"),
               _stl, family="STL"),
    ScanFormat(".obj", "shapeverify.io.mesh_scan:read_obj_scan", ("model/obj",), _obj,
               family="OBJ"),
)
_BY_SUFFIX = {f.suffix: f for f in SCAN_FORMATS}


class _Readers(Mapping):
    """suffix -> reader function, imported on first use."""

    def __getitem__(self, suffix):
        return _BY_SUFFIX[suffix].load()

    def __iter__(self):
        return iter(_BY_SUFFIX)

    def __len__(self):
        return len(_BY_SUFFIX)


#: file suffix (lower case, with the dot) -> reader ``(data: bytes, name: str) -> (N, 3) array``
SCAN_READERS: Mapping[str, Callable] = _Readers()
#: The suffixes of the scan files shapeverify reads (the one list).
SCAN_SUFFIXES = tuple(f.suffix for f in SCAN_FORMATS)
#: content type -> suffix, of every format (the service's table)
SCAN_CONTENT_TYPES = {t: f.suffix for f in SCAN_FORMATS for t in f.content_types}


def scan_format(fmt: str, name: str | None = None) -> ScanFormat:
    """The :class:`ScanFormat` of ``fmt``: a suffix with or without the dot, any case.

    Raises
    ------
    UnsupportedFormatError
        ``fmt`` is not one of :data:`SCAN_SUFFIXES` (the message lists them).
    """
    key = str(fmt).strip().lower()
    key = key if key.startswith(".") else "." + key
    f = _BY_SUFFIX.get(key)
    if f is None:
        where = f"{name}: " if name else ""
        raise UnsupportedFormatError(f"{where}unsupported point-cloud extension {fmt!r}; "
                                     f"supported: {', '.join(SCAN_SUFFIXES)}")
    return f


def scan_families() -> dict[str, tuple[str, ...]]:
    """Content family -> its suffixes, in the registry's order (``{"PLY": (".ply",), "text":
    (".xyz", ".txt", ".csv"), ...}``)."""
    out: dict[str, tuple[str, ...]] = {}
    for f in SCAN_FORMATS:
        out[f.family] = out.get(f.family, ()) + (f.suffix,)
    return out


def scan_help() -> str:
    """The CLI's words for the scan files it reads: the suffixes, and the units."""
    other = [f"{f.suffix} files are {_UNIT_WORDS.get(f.unit, f.unit)}, converted"
             for f in SCAN_FORMATS if f.unit != "mm"]
    return f"{' '.join(SCAN_SUFFIXES)} (mm" + "".join(f"; {o}" for o in other) + ")"


_UNIT_WORDS = {"m": "metres", "in": "inches", "um": "micrometres"}


def scan_reader(fmt: str, name: str | None = None) -> Callable:
    """The reader of format ``fmt``: a suffix with or without the dot, any case (``"ply"``,
    ``".PLY"``).

    Raises
    ------
    UnsupportedFormatError
        ``fmt`` is not one of :data:`SCAN_SUFFIXES` (the message lists them).
    """
    return scan_format(fmt, name).load()


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


# model files a content sniff tells apart too (for messages): family -> (suffix, test)
_MODEL_FAMILIES = {
    "STEP": (".step", lambda head: head.lstrip().startswith(b"ISO-10303-21")),
    "IGES": (".igs", lambda head: len(head) >= 80 and head[72:73] == b"S"
             and head[73:80].strip().isdigit()),
}
_MODEL_SUFFIXES = {".step": "STEP", ".stp": "STEP", ".igs": "IGES", ".iges": "IGES"}


def sniff_scan(data: bytes) -> ScanFormat | None:
    """The first format of :data:`SCAN_FORMATS` whose magic the content has, or None (plain text
    tables and unknown content).

    >>> sniff_scan(b"LASF" + bytes(300)).suffix
    '.las'
    """
    for f in SCAN_FORMATS:
        if f.matches(data):
            return f
    return None


def sniff_format(data: bytes) -> str | None:
    """What a file's first bytes say it is: the family of a scan format (``"PLY"``, ``"NumPy
    .npy"``, ``"PCD"``, ``"E57"``, ``"LAS"``, ``"STL"``, ``"OBJ"``), ``"STEP"`` or ``"IGES"``,
    or None (plain text tables and unknown content).

    Only for messages: the readers never guess a format from the content.

    >>> sniff_format(b"ply\\nformat ascii 1.0\\n"), sniff_format(b"1 2 3\\n")
    ('PLY', None)
    """
    f = sniff_scan(data)
    if f is not None:
        return f.family
    head = bytes(data[:4096])
    for family, (_, test) in _MODEL_FAMILIES.items():
        if test(head):
            return family
    return None


def suffix_hint(data: bytes, suffix: str | None) -> str:
    """``"; the content looks like a PLY file: give it the suffix .ply"`` when the content's
    format (:func:`sniff_format`) is not the one its suffix names, else ``""``."""
    seems = sniff_format(data)
    key = str(suffix or "").strip().lower()
    key = key if key.startswith(".") or not key else "." + key   # "ply" as format= gives it
    family = _BY_SUFFIX[key].family if key in _BY_SUFFIX else _MODEL_SUFFIXES.get(key)
    if seems is None or family == seems:
        return ""
    article = "an" if seems in ("STL", "IGES", "OBJ") else "a"
    return f"; the content looks like {article} {seems} file: give it the suffix {_suffix_of(seems)}"


def _suffix_of(family: str) -> str:
    """The suffix of a content family (the first format of the registry that has it)."""
    if family in _MODEL_FAMILIES:
        return _MODEL_FAMILIES[family][0]
    return next(f.suffix for f in SCAN_FORMATS if f.family == family)
