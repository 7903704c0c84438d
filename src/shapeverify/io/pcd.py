"""Point Cloud Library ``.pcd`` files with ``DATA ascii``, ``binary`` or ``binary_compressed``
and fields ``x y z``.

The header's point count (``POINTS``, ``WIDTH x HEIGHT``) must match the data: more or less data
than declared is an error that gives both numbers.  ``binary_compressed`` (PCL's LZF-compressed
fields, one after the other) is decompressed by :mod:`shapeverify.io.lzf` after its two sizes
are checked against the header and the file.
"""

from __future__ import annotations

import struct

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["read_pcd"]

_MAX_HEADER = 1 << 20   # a PCD header is a dozen short lines
_CODES = {"F": "f", "I": "i", "U": "u"}


def read_pcd(data: bytes, name: str) -> np.ndarray:
    """The fields ``x y z`` of a PCD file's bytes, (N, 3) float64 as stored."""
    hdr: dict[str, list[str]] = {}
    pos = 0
    while True:
        nl = data.find(b"\n", pos, _MAX_HEADER)
        if nl < 0:
            raise ScanError(f"{name}: malformed PCD header: no DATA line"
                            + (" in the first MiB" if len(data) > _MAX_HEADER else ""))
        line = data[pos:nl].decode("ascii", "replace").strip()
        pos = nl + 1
        if not line or line.startswith("#"):
            continue
        tok = line.split()
        key = tok[0].upper()
        if key in hdr:   # two POINTS (or FIELDS...) lines: which one holds is anybody's guess
            raise ScanError(f"{name}: malformed PCD header: {tok[0][:20]!r} appears twice")
        if not key[:1].isalpha():
            raise ScanError(f"{name}: malformed PCD header: line {line[:40]!r} is not "
                            "'KEYWORD values' (is a header line broken in two?)")
        hdr[key] = tok[1:]
        if tok[0].upper() == "DATA":
            break
    kind = (hdr["DATA"] or ["?"])[0].lower()
    if kind not in ("ascii", "binary", "binary_compressed"):
        raise ScanError(f"{name}: malformed PCD header: unknown DATA {kind!r}")
    try:
        fields = hdr["FIELDS"]
        nf = len(fields)
        sizes = [int(s) for s in hdr.get("SIZE", [])]
        types = [t.upper() for t in hdr.get("TYPE", [])]
        counts = [int(c) for c in hdr.get("COUNT", ["1"] * nf)]
        grid = None
        if "WIDTH" in hdr:
            grid = (int(hdr["WIDTH"][0]), int(hdr.get("HEIGHT", ["1"])[0]))
        npts = int(hdr["POINTS"][0]) if "POINTS" in hdr else grid[0] * grid[1]
    except (KeyError, ValueError, IndexError, TypeError) as exc:
        what = str(exc)[:60] if isinstance(exc, ValueError) else repr(exc)
        raise ScanError(f"{name}: malformed PCD header ({what} missing or not a number)") from None
    if grid is not None and grid[0] * grid[1] != npts:
        raise ScanError(f"{name}: malformed PCD header: WIDTH x HEIGHT = {grid[0]} x {grid[1]} = "
                        f"{grid[0] * grid[1]} disagrees with POINTS {npts}; correct one of them")
    if not (len(sizes) == len(types) == len(counts) == nf):
        raise ScanError(f"{name}: malformed PCD header: FIELDS, SIZE, TYPE and COUNT have "
                        f"different lengths ({nf}, {len(sizes)}, {len(types)}, {len(counts)})")
    for c in "xyz":
        if fields.count(c) > 1:
            raise ScanError(f"{name}: PCD field '{c}' appears {fields.count(c)} times in FIELDS "
                            f"({' '.join(fields)[:80]})")
        if c not in fields:
            raise ScanError(f"{name}: PCD has no field '{c}' (fields: {' '.join(fields)})")
    if npts == 0:
        raise ScanError(f"{name}: PCD contains no points (POINTS 0)")
    for c in "xyz":
        if counts[fields.index(c)] != 1:
            raise ScanError(f"{name}: PCD field '{c}' has COUNT {counts[fields.index(c)]}; "
                            "x, y and z must be single values (COUNT 1)")
    if npts < 0 or min(counts) < 1:
        raise ScanError(f"{name}: malformed PCD header: POINTS ({npts}) and COUNT "
                        f"({' '.join(map(str, counts))}) must be positive")
    if sum(c * s for c, s in zip(counts, sizes)) > len(data):
        raise ScanError(f"{name}: malformed PCD header: COUNT {' '.join(map(str, counts))} "
                        f"is larger than the whole file")
    codes = []
    for f, s, t in zip(fields, sizes, types):
        if t not in _CODES or s not in (1, 2, 4, 8) or (t == "F" and s not in (4, 8)):
            raise ScanError(f"{name}: PCD field {f[:40]!r} has unsupported TYPE {t[:20]} SIZE "
                            f"{s}: TYPE is one letter, F (float, SIZE 4 or 8), I or U (integer, "
                            "SIZE 1, 2, 4 or 8)")
        codes.append(_CODES[t] + str(s))
    if kind == "binary_compressed":
        return _compressed(data, pos, name, fields, codes, counts, npts)
    if kind == "binary":
        dt = np.dtype([(f"f{j}", "<" + code, (cnt,)) if cnt > 1 else (f"f{j}", "<" + code)
                       for j, (code, cnt) in enumerate(zip(codes, counts))])
        need = npts * dt.itemsize
        if len(data) - pos < need:
            raise ScanError(f"{name}: truncated PCD: {npts} points need {need} bytes, "
                            f"{len(data) - pos} present")
        tail = data[pos + need:]
        if tail and (len(tail) >= max(dt.itemsize, 4) or tail.strip(b" \t\r\n")):
            found = (len(data) - pos) / dt.itemsize
            raise ScanError(f"{name}: the PCD header declares {npts} points ({need} bytes), the "
                            f"data holds {len(data) - pos} bytes ({found:.6g} points): POINTS "
                            "is too small, or data was inserted or appended; correct POINTS "
                            "(and WIDTH, HEIGHT)")
        rec = np.frombuffer(data, dtype=dt, count=npts, offset=pos)
        with np.errstate(invalid="ignore", over="ignore"):   # NaN/inf: dropped and reported later
            return np.column_stack([rec[f"f{fields.index(c)}"].astype(np.float64) for c in "xyz"])
    text = data[pos:].decode("ascii", "replace").splitlines()
    try:
        table = np.loadtxt(text, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise ScanError(f"{name}: malformed PCD ascii data: {exc}") from None
    ncol = sum(counts)
    if table.shape[1] != ncol:
        raise ScanError(f"{name}: PCD rows have {table.shape[1]} values, header declares {ncol}")
    if table.shape[0] != npts:
        raise ScanError(f"{name}: PCD header declares {npts} points, file has {table.shape[0]}")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return table[:, [starts[fields.index(c)] for c in "xyz"]]


def _compressed(data: bytes, pos: int, name: str, fields, codes, counts, npts: int) -> np.ndarray:
    """x y z of ``DATA binary_compressed``: two uint32 (compressed and uncompressed size), then
    LZF data that decodes to each field's values for all points, field after field."""
    if len(data) - pos < 8:
        raise ScanError(f"{name}: truncated PCD: binary_compressed data without its sizes")
    csize, usize = struct.unpack_from("<II", data, pos)
    rest = len(data) - pos - 8
    if csize > rest:
        raise ScanError(f"{name}: truncated PCD: the compressed block declares {csize} bytes, "
                        f"{rest} present")
    tail = data[pos + 8 + csize:]
    if tail and (len(tail) >= 4 or tail.strip(b" \t\r\n")):
        raise ScanError(f"{name}: the PCD compressed block declares {csize} bytes, the file holds "
                        f"{rest}: data was inserted or appended")
    sizes = [int(c[1:]) * cnt for c, cnt in zip(codes, counts)]
    need = npts * sum(sizes)
    if usize != need:
        raise ScanError(f"{name}: the PCD header declares {npts} points ({need} bytes of fields), "
                        f"the compressed block holds {usize} bytes "
                        f"({usize / max(sum(sizes), 1):.6g} points); correct POINTS (and WIDTH, "
                        "HEIGHT)")
    from shapeverify.io.lzf import lzf_decompress

    raw = lzf_decompress(data[pos + 8: pos + 8 + csize], usize, name)
    starts = np.concatenate([[0], np.cumsum([npts * s for s in sizes])[:-1]]).astype(int)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.column_stack([
            np.frombuffer(raw, "<" + codes[fields.index(c)], npts, int(starts[fields.index(c)]))
            .astype(np.float64) for c in "xyz"])
