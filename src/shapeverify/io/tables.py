"""Point tables (``.xyz .txt .csv``): one point per line, separated by whitespace, ``,`` or ``;``.

An optional header line; ``#`` and ``//`` comments; the first three columns are ``x y z``,
further columns are ignored.
"""

from __future__ import annotations

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["read_table"]


def read_table(data: bytes, name: str) -> np.ndarray:
    """The first three columns of a point table's bytes, (N, 3) float64 as stored."""
    text = data.decode("utf-8", errors="replace")
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines)
                  if ln.strip() and not ln.lstrip().startswith(("#", "//"))), None)
    if first is None:
        raise ScanError(f"{name}: contains no points (only blank or comment lines)")
    delim = _split_pattern(lines[first])
    skip = first
    if not _is_numeric_row(lines[first], delim):
        skip = first + 1  # one header line
        nxt = next((i for i in range(skip, len(lines))
                    if lines[i].strip() and not lines[i].lstrip().startswith(("#", "//"))), None)
        if nxt is None:
            raise ScanError(f"{name}: contains a header line but no points")
        delim = _split_pattern(lines[nxt])
    try:
        table = np.loadtxt(lines[skip:], dtype=np.float64, delimiter=delim, comments=("#", "//"),
                           ndmin=2)
    except ValueError as exc:
        raise ScanError(f"{name}: malformed point table: {exc}") from None
    if table.shape[0] == 0:
        raise ScanError(f"{name}: contains no points")
    if table.shape[1] < 3:
        raise ScanError(f"{name}: has {table.shape[1]} column(s); need at least 3 (x y z)")
    return table[:, :3]


def _split_pattern(line: str):
    if "," in line:
        return ","
    if ";" in line:
        return ";"
    return None


def _is_numeric_row(line: str, delim) -> bool:
    tok = [t for t in (line.split(delim) if delim else line.split()) if t.strip()]
    try:
        [float(t) for t in tok[:3]]
    except ValueError:
        return False
    return bool(tok)
