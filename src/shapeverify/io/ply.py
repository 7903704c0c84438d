"""PLY files: read (ascii, binary little and big endian) and write, as bytes or a file.

Readers take the file's bytes and a ``name`` that stands for it in error messages (the
registry in :mod:`shapeverify.io.formats` turns a path, bytes or a file object into those).
"""

from __future__ import annotations

import io
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["PlyData", "read_ply_full", "read_ply_points", "ply_bytes", "write_ply", "parse_ply"]

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}


@dataclass(frozen=True, repr=False)
class PlyData:
    """Content of a PLY file: vertices, (triangulated) faces and the other vertex properties.

    Attributes
    ----------
    vertices : (V, 3) float64
        ``x y z`` of element ``vertex``, as stored (non-finite rows are *not* removed, so that
        face indices stay valid).
    faces : (T, 3) int64 or None
        Triangles (polygons fan-triangulated: ``(p0, pi, pi+1)``); None when the file has no
        face element or it is empty.
    properties : dict[str, (V,) ndarray]
        Every other scalar property of element ``vertex`` (e.g. ``nx ny nz``, ``red green
        blue``, scalar fields), with the file's dtype.
    format : str
        ``ascii``, ``binary_little_endian`` or ``binary_big_endian``.
    """

    vertices: np.ndarray
    faces: np.ndarray | None
    properties: dict = field(default_factory=dict)
    format: str = "ascii"

    def __repr__(self) -> str:
        nf = 0 if self.faces is None else len(self.faces)
        return (f"PlyData(vertices={len(self.vertices)}, faces={nf}, "
                f"properties={sorted(self.properties)}, format={self.format!r})")


def read_ply_full(source, *, name: str | None = None) -> PlyData:
    """Read a PLY file with its faces and all vertex properties (for mesh references and for
    reading back coloured reports).

    Parameters
    ----------
    source : str, os.PathLike, bytes or binary file object
        The file, or its content.
    name : str, optional
        Stands for the data in error messages (default: the path, or the file object's name).

    Returns
    -------
    PlyData

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ScanError
        Empty, truncated or malformed file; no ``x y z``; face indices out of range.
    """
    from shapeverify.io.formats import source_bytes

    data, name = source_bytes(source, name)
    try:
        return parse_ply(data, name, want_faces=True)
    except ScanError as exc:  # a file of another format named .ply: say which
        from shapeverify.io.formats import suffix_hint

        hint = suffix_hint(data, ".ply")
        if hint:
            raise ScanError(f"{exc}{hint}") from None
        raise


def read_ply_points(data: bytes, name: str) -> np.ndarray:
    """The ``x y z`` of element ``vertex`` of a PLY file's bytes, (N, 3) float64 as stored
    (the scan reader of :mod:`shapeverify.io.formats`)."""
    return parse_ply(data, name, want_faces=False).vertices


def ply_bytes(points, normals=None, colors=None, scalars=None, binary=True, faces=None) -> bytes:
    """Encode points (and optionally normals, colours, scalar fields, triangles) as a PLY file.

    Coordinates, normals and scalars are written as ``double`` (lossless round trip),
    colours as ``uchar red green blue [alpha]``.

    Parameters
    ----------
    points : (N, 3) array_like, finite
    normals : (N, 3) array_like, optional
        Written as ``nx ny nz``.
    colors : (N, 3) or (N, 4) array_like, optional
        Integers 0..255, or floats in [0, 1] (scaled by 255 and rounded).
    scalars : dict[str, (N,) array_like], optional
        Extra per-vertex scalar properties (e.g. ``{"deviation": d}``).  Names must be
        identifiers and must not clash with the standard ones.
    binary : bool
        ``binary_little_endian`` (default) or ``ascii``.
    faces : (T, 3) array_like of int, optional
        Triangles (indices into ``points``), written as element ``face``.

    Returns
    -------
    bytes
        The file's content (:func:`write_ply` writes it to a path).

    Raises
    ------
    ValueError
        Wrong shapes, non-finite points, bad colours, bad scalar names, face indices out of range.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError("points contain NaN or inf; remove those rows before writing")
    n = len(pts)
    cols = [("x", pts[:, 0]), ("y", pts[:, 1]), ("z", pts[:, 2])]
    if normals is not None:
        nrm = np.asarray(normals, dtype=np.float64)
        if nrm.shape != (n, 3):
            raise ValueError(f"normals must have shape ({n}, 3) like points, got {nrm.shape}")
        cols += [("nx", nrm[:, 0]), ("ny", nrm[:, 1]), ("nz", nrm[:, 2])]
    if colors is not None:
        col = np.asarray(colors)
        if col.ndim != 2 or col.shape[0] != n or col.shape[1] not in (3, 4):
            raise ValueError(f"colors must have shape ({n}, 3) or ({n}, 4), got {col.shape}")
        if np.issubdtype(col.dtype, np.floating):
            if not (np.isfinite(col).all() and col.min(initial=0) >= 0 and col.max(initial=0) <= 1):
                raise ValueError("float colors must lie in [0, 1] (or pass uint8 0..255)")
            col = np.rint(col * 255.0)
        elif not np.issubdtype(col.dtype, np.integer):
            raise ValueError(f"colors must be integers 0..255 or floats in [0, 1], got {col.dtype}")
        if col.size and (col.min() < 0 or col.max() > 255):
            raise ValueError("integer colors must lie in 0..255")
        col = col.astype(np.uint8)
        for i, name in enumerate(("red", "green", "blue", "alpha")[: col.shape[1]]):
            cols.append((name, col[:, i]))
    if scalars:
        taken = {c[0] for c in cols}
        for name, arr in scalars.items():
            if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
                raise ValueError(f"scalar name {name!r} must be an identifier (letters, digits, _)")
            if name in taken:
                raise ValueError(f"scalar name {name!r} clashes with another vertex property")
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != (n,):
                raise ValueError(f"scalar {name!r} must have shape ({n},), got {a.shape}")
            cols.append((name, a))
            taken.add(name)
    tri = None
    if faces is not None:
        tri = np.asarray(faces)
        if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
            raise ValueError(f"faces must be an integer (T, 3) array, got {tri.dtype} {tri.shape}")
        if tri.size and (tri.min() < 0 or tri.max() >= n):
            raise ValueError(f"face indices must lie in [0, {n}), got [{tri.min()}, {tri.max()}]")

    fmt = "binary_little_endian" if binary else "ascii"
    header = ["ply", f"format {fmt} 1.0", "comment written by shapeverify",
              f"element vertex {n}"]
    for name, a in cols:
        header.append(f"property {'uchar' if a.dtype == np.uint8 else 'double'} {name}")
    if tri is not None:
        header += [f"element face {len(tri)}", "property list uchar int vertex_indices"]
    header.append("end_header")
    with io.BytesIO() as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        if binary:
            dt = np.dtype([(name, "u1" if a.dtype == np.uint8 else "<f8") for name, a in cols])
            rec = np.empty(n, dtype=dt)
            for name, a in cols:
                rec[name] = a
            fh.write(rec.tobytes())
            if tri is not None:
                frec = np.empty(len(tri), dtype=[("n", "u1"), ("i", "<i4", (3,))])
                frec["n"] = 3
                frec["i"] = tri
                fh.write(frec.tobytes())
        else:
            fmts = ["%d" if a.dtype == np.uint8 else "%.17g" for _, a in cols]
            table = np.column_stack([a.astype(np.float64) for _, a in cols]) if n else \
                np.empty((0, len(cols)))
            np.savetxt(fh, table, fmt=fmts)
            if tri is not None:
                np.savetxt(fh, np.column_stack([np.full(len(tri), 3), tri]), fmt="%d")
        return fh.getvalue()


def write_ply(path, points, normals=None, colors=None, scalars=None, binary=True, faces=None):
    """Write points (and optionally normals, colours, scalar fields, triangles) to a PLY file.

    Parameters as :func:`ply_bytes`; ``path`` (str or os.PathLike) is the file written.

    Returns
    -------
    pathlib.Path
        The written path.

    Raises
    ------
    ValueError
        As :func:`ply_bytes` (nothing is written then).
    """
    data = ply_bytes(points, normals=normals, colors=colors, scalars=scalars, binary=binary,
                     faces=faces)
    path = Path(path)
    path.write_bytes(data)
    return path


# ---------------------------------------------------------------------------------------- PLY
@dataclass
class _PlyElement:
    name: str
    count: int
    props: list  # (name, dtype_code) or (name, count_code, item_code)
    names: set = field(default_factory=set)  # the property names, for the duplicate check


#: Most elements and properties per element a PLY header may declare (real files have a few
#: elements and tens of properties; a header beyond these is damaged or hostile).
MAX_PLY_ELEMENTS = 64
MAX_PLY_PROPERTIES = 1024


def _ply_header(name: str, data: bytes):
    """Parse the PLY header in time linear in its length; return (format, elements, body offset).

    Raises
    ------
    ScanError
        A malformed header, or one with more than :data:`MAX_PLY_ELEMENTS` elements or
        :data:`MAX_PLY_PROPERTIES` properties in an element.
    """
    if not data.startswith(b"ply"):
        raise ScanError(f"{name}: not a PLY file (does not start with 'ply')")
    m = re.search(rb"end_header[ \t]*\r?\n", data[:1 << 20])
    if m is None:
        # a header without body is still a header if the file ends right after end_header
        m = re.search(rb"end_header[ \t]*\r?\n?$", data[:1 << 20])
        if m is None:
            raise ScanError(f"{name}: malformed PLY header: no 'end_header' line (in the "
                            "first MiB)")
    text = data[: m.start()].decode("ascii", errors="replace")
    fmt = None
    elements: list[_PlyElement] = []
    element_names: set = set()
    for lineno, raw in enumerate(text.splitlines()[1:], start=2):
        tok = raw.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        bad = f"{name}: malformed PLY header at line {lineno} ({raw.strip()[:80]!r})"
        if tok[0] == "format":
            if len(tok) < 2 or tok[1] not in _PLY_FORMATS:
                raise ScanError(f"{bad}: unknown format; expected ascii, "
                                "binary_little_endian or binary_big_endian")
            fmt = tok[1]
        elif tok[0] == "element":
            if len(tok) != 3 or not (tok[2].isascii() and tok[2].isdigit()):
                raise ScanError(f"{bad}: expected 'element NAME COUNT'")
            if tok[1] in element_names:
                raise ScanError(f"{bad}: element {tok[1]!r} declared twice")
            if len(elements) >= MAX_PLY_ELEMENTS:
                raise ScanError(f"{name}: the PLY header declares more than {MAX_PLY_ELEMENTS} "
                                f"elements (line {lineno}): the file is damaged, or not a scan "
                                "this reader supports")
            if len(tok[2]) > 19:  # beyond any file size in bytes (and int64)
                raise ScanError(f"{bad}: element count {tok[2][:30]} is absurd")
            element_names.add(tok[1])
            elements.append(_PlyElement(tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            if not elements:
                raise ScanError(f"{bad}: property before any element")
            el = elements[-1]
            if tok[-1] in el.names:
                raise ScanError(f"{bad}: property {tok[-1]!r} declared twice")
            if len(el.props) >= MAX_PLY_PROPERTIES:
                raise ScanError(f"{name}: element {el.name!r} of the PLY header declares more "
                                f"than {MAX_PLY_PROPERTIES} properties (line {lineno}): the file "
                                "is damaged, or not a scan this reader supports")
            if len(tok) == 3 and tok[1] in _PLY_TYPES:
                el.props.append((tok[2], _PLY_TYPES[tok[1]]))
            elif (len(tok) == 5 and tok[1] == "list" and tok[2] in _PLY_TYPES
                  and tok[3] in _PLY_TYPES and _PLY_TYPES[tok[2]][0] in "iu"):
                el.props.append((tok[4], _PLY_TYPES[tok[2]], _PLY_TYPES[tok[3]]))
            else:
                raise ScanError(f"{bad}: unknown property type")
            el.names.add(tok[-1])
        else:
            raise ScanError(f"{bad}: unknown keyword {tok[0]!r}")
    if fmt is None:
        raise ScanError(f"{name}: malformed PLY header: no 'format' line")
    return fmt, elements, m.end()


def parse_ply(data: bytes, name: str, want_faces: bool) -> PlyData:
    """Parse a whole PLY file's bytes; ``name`` stands for the file in error messages."""
    fmt, elements, offset = _ply_header(name, data)
    names = [e.name for e in elements]
    if "vertex" not in names:
        raise ScanError(f"{name}: PLY file has no 'vertex' element")
    vel = elements[names.index("vertex")]
    vnames = [p[0] for p in vel.props]
    for c in "xyz":
        if c not in vnames:
            raise ScanError(f"{name}: PLY vertex element has no '{c}' property "
                            f"(properties: {', '.join(vnames) or 'none'})")
        if len(vel.props[vnames.index(c)]) != 2:
            raise ScanError(f"{name}: PLY vertex property '{c}' is a list; it must be a scalar "
                            "(e.g. 'property float x')")
    if vel.count == 0:
        raise ScanError(f"{name}: PLY file has no vertices (element vertex 0)")
    wanted = {"vertex"} | ({"face"} if want_faces else set())
    last = max(i for i, e in enumerate(elements) if e.name in wanted)
    values = {}
    if fmt == "ascii":
        lines = [ln for ln in data[offset:].split(b"\n") if ln.strip()]
        pos = 0
        for i, el in enumerate(elements[: last + 1]):
            chunk = lines[pos: pos + el.count]
            if len(chunk) < el.count:
                raise ScanError(f"{name}: truncated PLY: element {el.name!r} needs {el.count} "
                                f"lines, found {len(chunk)}")
            if el.name in wanted:
                values[el.name] = _ply_ascii_element(name, el, chunk)
            pos += el.count
        declared = sum(e.count for e in elements)
        if len(lines) > declared:
            counts = ", ".join(f"{e.name} {e.count}" for e in elements)
            raise ScanError(f"{name}: the PLY header declares {declared} lines of data "
                            f"({counts}), the file has {len(lines)}: the element counts in the "
                            "header are too small (or data was appended); correct the "
                            "'element' lines")
        if len(lines) < declared:   # an element after the ones read is short
            counts = ", ".join(f"{e.name} {e.count}" for e in elements)
            raise ScanError(f"{name}: truncated PLY: the header declares {declared} lines of "
                            f"data ({counts}), the file has {len(lines)}")
    else:
        endian = _PLY_FORMATS[fmt]
        for el in elements[: last + 1]:
            arrays, offset = _ply_binary_element(name, el, data, offset, endian,
                                                 parse=el.name in wanted)
            if el.name in wanted:
                values[el.name] = arrays
        _check_binary_end(name, elements, last, data, offset, endian)

    v = values["vertex"]
    vertices = np.column_stack([np.asarray(v[c], dtype=np.float64) for c in "xyz"])
    props = {k: a for k, a in v.items()
             if k not in ("x", "y", "z") and isinstance(a, np.ndarray) and a.ndim == 1}
    faces = None
    if want_faces and "face" in values and elements[names.index("face")].count > 0:
        fel = elements[names.index("face")]
        lists = [p[0] for p in fel.props if len(p) == 3]
        if not lists:
            raise ScanError(f"{name}: PLY face element has no list property of vertex indices")
        key = "vertex_indices" if "vertex_indices" in lists else \
            "vertex_index" if "vertex_index" in lists else lists[0]
        faces = _fan_triangulate(name, values["face"][key], len(vertices))
    return PlyData(vertices, faces, props, fmt)


def _check_binary_end(name, elements, last: int, data: bytes, offset: int, endian: str) -> None:
    """Refuse a binary PLY whose data does not end where its header says: more data after the
    declared elements (their counts are too small, or bytes were inserted: part of the data
    would be ignored or read shifted), or elements after ``last`` (not parsed) that are
    truncated.  Whitespace shorter than a record after the data (a stray newline) is allowed."""
    for el in elements[last + 1:]:
        _, offset = _ply_binary_element(name, el, data, offset, endian, parse=False)
    tail = data[offset:]
    if not tail:
        return
    unit = min((sum(np.dtype(p[1]).itemsize for p in el.props)
                for el in elements if el.props and not any(len(p) == 3 for p in el.props)),
               default=0)
    if len(tail) < max(unit, 4) and not tail.strip(b" \t\r\n"):
        return
    counts = ", ".join(f"{e.name} {e.count}" for e in elements)
    raise ScanError(f"{name}: {len(tail)} bytes follow the data the PLY header declares "
                    f"({counts}): the element counts in the header are too small, or data was "
                    "inserted or appended; correct the 'element' lines")


def _ply_ascii_element(name, el: _PlyElement, lines: list) -> dict:
    """Parse the lines of one ASCII element into {property: array}; list -> (count, n) array or
    list of arrays."""
    ncols_fixed = None
    try:
        table = np.loadtxt([ln.decode("ascii", "replace") for ln in lines], dtype=np.float64,
                           ndmin=2, comments=None)
        ncols_fixed = table.shape[1]
    except ValueError:
        table = None
    if table is not None and not any(len(p) == 3 for p in el.props):
        if ncols_fixed != len(el.props):
            raise ScanError(f"{name}: PLY element {el.name!r} has {ncols_fixed} values per line, "
                            f"header declares {len(el.props)} properties")
        return {p[0]: table[:, j] for j, p in enumerate(el.props)}
    out = {}
    if table is not None:  # same token count on every line: walk the columns
        col = 0
        ok = True
        for p in el.props:
            if col >= table.shape[1]:
                ok = False
                break
            if len(p) == 2:
                out[p[0]] = table[:, col]
                col += 1
            else:
                cnt = table[:, col]
                k = int(cnt[0]) if np.isfinite(cnt[0]) and 0 <= cnt[0] <= table.shape[1] else -1
                if k < 0 or not np.all(cnt == k) or col + 1 + k > table.shape[1]:
                    ok = False
                    break
                out[p[0]] = table[:, col + 1: col + 1 + k]
                col += 1 + k
        if ok and col == table.shape[1]:
            return out
    # ragged rows: line by line
    cols = {p[0]: [] for p in el.props}
    for lineno, ln in enumerate(lines):
        tok = ln.split()
        j = 0
        try:
            for p in el.props:
                if len(p) == 2:
                    cols[p[0]].append(float(tok[j]))
                    j += 1
                else:
                    k = int(tok[j])
                    if k < 0:
                        raise ValueError
                    cols[p[0]].append(np.array(tok[j + 1: j + 1 + k], dtype=np.float64))
                    if len(cols[p[0]][-1]) != k:
                        raise IndexError
                    j += 1 + k
        except (IndexError, ValueError):
            raise ScanError(f"{name}: malformed PLY element {el.name!r}, item {lineno}: "
                            f"{ln[:80].decode('ascii', 'replace')!r}") from None
        if j != len(tok):
            raise ScanError(f"{name}: PLY element {el.name!r}, item {lineno} has {len(tok)} "
                            f"values, expected {j}")
    for p in el.props:
        out[p[0]] = np.array(cols[p[0]]) if len(p) == 2 else cols[p[0]]
    return out


def _ply_binary_element(name, el: _PlyElement, data: bytes, offset: int, endian: str,
                        parse: bool):
    """Parse (or skip) one binary element; return ({property: array}, new offset)."""
    has_list = any(len(p) == 3 for p in el.props)
    if not has_list:
        dt = np.dtype([(f"f{j}", endian + p[1]) for j, p in enumerate(el.props)])
        end = offset + el.count * dt.itemsize
        if end > len(data):
            raise ScanError(f"{name}: truncated PLY: element {el.name!r} needs "
                            f"{el.count * dt.itemsize} bytes, {len(data) - offset} left")
        if not parse:
            return None, end
        rec = np.frombuffer(data, dtype=dt, count=el.count, offset=offset)
        return {p[0]: rec[f"f{j}"] for j, p in enumerate(el.props)}, end
    if el.count == 0:
        return {p[0]: np.empty((0, 0)) for p in el.props}, offset
    # fast name: every list has the length found in the first item
    fields = []
    pos = offset
    try:
        for j, p in enumerate(el.props):
            if len(p) == 2:
                fields.append((f"f{j}", endian + p[1]))
                pos += np.dtype(p[1]).itemsize
            else:
                k = int(np.frombuffer(data, endian + p[1], 1, pos)[0])
                if k < 0 or k * np.dtype(p[2]).itemsize > len(data):
                    raise ScanError(f"{name}: malformed PLY: list '{p[0]}' of element "
                                    f"{el.name!r} has length {k}")
                fields.append((f"c{j}", endian + p[1]))
                fields.append((f"f{j}", endian + p[2], (k,)))
                pos += np.dtype(p[1]).itemsize + k * np.dtype(p[2]).itemsize
    except ValueError as exc:
        if isinstance(exc, ScanError):
            raise
        raise ScanError(f"{name}: truncated PLY in element {el.name!r}") from None
    dt = np.dtype(fields)
    end = offset + el.count * dt.itemsize
    if end <= len(data):
        rec = np.frombuffer(data, dtype=dt, count=el.count, offset=offset)
        if all(np.all(rec[f"c{j}"] == dt[f"f{j}"].shape[0])
               for j, p in enumerate(el.props) if len(p) == 3):
            if not parse:
                return None, end
            return {p[0]: rec[f"f{j}"] for j, p in enumerate(el.props)}, end
    # slow name: variable-length lists, item by item
    out = {p[0]: [] for p in el.props}
    pos = offset
    try:
        for _ in range(el.count):
            for p in el.props:
                if len(p) == 2:
                    size = np.dtype(p[1]).itemsize
                    out[p[0]].append(struct.unpack_from(endian + _STRUCT[p[1]], data, pos)[0])
                    pos += size
                else:
                    k = struct.unpack_from(endian + _STRUCT[p[1]], data, pos)[0]
                    pos += np.dtype(p[1]).itemsize
                    isz = np.dtype(p[2]).itemsize
                    if k < 0 or pos + k * isz > len(data):
                        raise struct.error
                    out[p[0]].append(np.frombuffer(data, endian + p[2], k, pos))
                    pos += k * isz
    except struct.error:
        raise ScanError(f"{name}: truncated PLY in element {el.name!r}") from None
    if not parse:
        return None, pos
    return {p[0]: (np.array(out[p[0]]) if len(p) == 2 else out[p[0]]) for p in el.props}, pos


_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f", "f8": "d"}


def _fan_triangulate(name, lists, n_vertices: int) -> np.ndarray:
    """Polygons (2-D array or list of 1-D arrays) -> (T, 3) int64 triangles by fans."""
    if isinstance(lists, np.ndarray) and lists.ndim == 2:
        groups = [lists]
    else:
        by_len: dict[int, list] = {}
        for poly in lists:
            by_len.setdefault(len(poly), []).append(poly)
        groups = [np.array(g) for g in by_len.values()]
    tris = []
    for g in groups:
        g = np.asarray(g)
        if g.shape[1] < 3:
            raise ScanError(f"{name}: face with {g.shape[1]} vertices (need at least 3)")
        if not np.all(np.isfinite(g)) or not np.all(g == np.round(g)):
            raise ScanError(f"{name}: face indices are not integers")
        g = g.astype(np.int64)
        for i in range(1, g.shape[1] - 1):
            tris.append(np.column_stack([g[:, 0], g[:, i], g[:, i + 1]]))
    tri = np.concatenate(tris) if tris else np.empty((0, 3), np.int64)
    if tri.size and (tri.min() < 0 or tri.max() >= n_vertices):
        raise ScanError(f"{name}: face vertex index out of range [0, {n_vertices}) "
                        f"(found {tri.min()}..{tri.max()})")
    return tri
