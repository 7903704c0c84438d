"""Point tables (``.xyz .txt .csv``): one point per line, separated by whitespace, ``,`` or ``;``.

An optional header line; ``#`` and ``//`` comments; the first three columns are ``x y z``,
further columns are ignored; a delimiter closing every row is allowed; with ``;`` as the
delimiter a decimal comma is read as a decimal point (``1,5;2,5;3,5``, European exports).  Text is UTF-8 (a byte-order mark is skipped) or, with its
byte-order mark, UTF-16 (as some Windows tools write it).
"""

from __future__ import annotations

import codecs

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["read_table"]

_COMMENTS = ("#", "//")


def _decode(data: bytes, name: str) -> str:
    """The text of a point table; binary content is refused with what it seems to be."""
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            raise ScanError(f"{name}: starts with a UTF-16 byte-order mark but is not valid "
                            "UTF-16 text; save the point table as UTF-8 text") from None
    if b"\0" in data[:4096]:
        raise ScanError(f"{name}: is binary data, not a text point table with x y z per line")
    return data.decode("utf-8-sig", errors="replace")


def _is_data(line: str) -> bool:
    s = line.strip()
    return bool(s) and not s.startswith(_COMMENTS)


def read_table(data: bytes, name: str) -> np.ndarray:
    """The first three columns of a point table's bytes, (N, 3) float64 as stored."""
    lines = _decode(data, name).splitlines()
    first = next((i for i, ln in enumerate(lines) if _is_data(ln)), None)
    if first is None:
        raise ScanError(f"{name}: contains no points (only blank or comment lines)")
    delim = _split_pattern(lines[first])
    skip = first
    if not _is_numeric_row(lines[first], delim):
        skip = first + 1  # one header line
        nxt = next((i for i in range(skip, len(lines)) if _is_data(lines[i])), None)
        if nxt is None:
            raise ScanError(f"{name}: contains a header line but no points")
        delim = _split_pattern(lines[nxt])
    rows = [ln if ln.strip() else "" for ln in lines[skip:]]  # blank lines (numpy skips "")
    if delim == ";" and any("," in ln for ln in rows[:50]):
        rows = [ln.replace(",", ".") for ln in rows]  # "1,5;2,5;3,5": decimal commas
    if delim is not None and rows and rows[0].rstrip().endswith(delim):
        rows = [ln.rstrip().rstrip(delim) for ln in rows]  # a delimiter closing every row
    try:
        table = np.loadtxt(rows, dtype=np.float64, delimiter=delim, comments=_COMMENTS,
                           ndmin=2)
    except ValueError:
        raise ScanError(_malformed(name, lines[:skip] + rows, skip, delim)) from None
    if table.shape[0] == 0:
        raise ScanError(f"{name}: contains no points")
    if table.shape[1] < 3:
        raise ScanError(f"{name}: has {table.shape[1]} column(s); need at least 3 (x y z)")
    return table[:, :3]


def _malformed(name: str, lines: list[str], skip: int, delim) -> str:
    """The message for a table numpy refused: the first bad line (1-based), what is wrong with
    it, and what the lines before it held."""
    ncol = None
    for i in range(skip, len(lines)):
        line = lines[i]
        if not _is_data(line):
            continue
        for c in _COMMENTS:
            line = line.split(c, 1)[0]
        tok = [t.strip() for t in (line.split(delim) if delim else line.split())]
        shown = lines[i].strip()[:60]
        try:
            [float(t) for t in tok]
        except ValueError:
            bad = next(t for t in tok if not _is_float(t))
            return (f"{name}, line {i + 1}: malformed point table: {bad[:20]!r} is not a number "
                    f"({shown!r}); a point table holds numbers only (x y z per line, one "
                    "optional header line)")
        if ncol is None:
            ncol = len(tok)
        elif len(tok) != ncol:
            return (f"{name}, line {i + 1}: malformed point table: {len(tok)} values where the "
                    f"lines before have {ncol} ({shown!r}); is the file truncated or are values "
                    "missing?")
    return f"{name}: malformed point table"


def _is_float(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _split_pattern(line: str):
    if ";" in line:   # before ",": "1,5;2,5;3,5" has decimal commas
        return ";"
    if "," in line:
        return ","
    return None


def _is_numeric_row(line: str, delim) -> bool:
    if delim == ";":
        line = line.replace(",", ".")
    tok = [t for t in (line.split(delim) if delim else line.split()) if t.strip()]
    # a header line starts with a name ("x y z", "X,Y,Z,I"); a line that starts with a number
    # and holds a word further on is a damaged data row (an error), not a header to skip
    return bool(tok) and _is_float(tok[0].split()[0])
