"""Point Cloud Library ``.pcd`` files with ``DATA ascii`` or ``DATA binary`` and fields ``x y z``.

``binary_compressed`` is not supported (:class:`~shapeverify.errors.UnsupportedFormatError`
names it and how to convert the file).
"""

from __future__ import annotations

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError

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
        hdr[tok[0].upper()] = tok[1:]
        if tok[0].upper() == "DATA":
            break
    kind = (hdr["DATA"] or ["?"])[0].lower()
    if kind == "binary_compressed":
        raise UnsupportedFormatError(
            f"{name}: PCD 'DATA binary_compressed' is not supported; convert it to binary or "
            "ascii (e.g. pcl_convert_pcd_ascii_binary in.pcd out.pcd 1)")
    if kind not in ("ascii", "binary"):
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
