"""Refuse numbers OpenCASCADE cannot hold before it reads a STEP or IGES file.

A point coordinate that is not a finite double -- ``NaN``, ``INF``, an exponent out of range
(``1.E+400``), a Fortran exponent in STEP (``9.99D+99``), or an omitted value ``*`` among a
point's coordinates -- is not something OpenCASCADE reads safely (issue 33 row 4: 14 of 1,059
mutated files kept ``info``/``prepare`` busy for over 900 s; measured here on the wavy cube:
``NaN`` and ``*`` over 60 s and still running, ``9.99D+99`` read silently as 9.99, ``1.E+400``
"no faces").  :func:`check_numbers` finds such a token by a
linear scan of the file's bytes and raises :class:`~shapeverify.errors.CADImportError` naming
the file, the line and the token, so the importer never sees the file.

How: a few vectorised numpy passes over the file with whitespace removed (``bytes.translate``)
find the places where such a token may stand; a regular expression confirms each (a hit inside
a STEP string is told apart by the parity of the quotes before it).  What is refused:

* STEP, the DATA section outside strings: a real with an exponent of three or more digits whose
  value overflows a double; a real with a ``D`` exponent (not STEP syntax); the words ``NAN``,
  ``INF``, ``INFINITY`` as a parameter; a ``*`` next to a real in a list (``(0.,*,1.)``).
* IGES, the parameter-data section (columns 1-64 of ``P`` lines): a real (``E`` or ``D``
  exponent) that overflows a double; ``NAN``/``INF`` as a parameter.
* Both: a finite real of magnitude :data:`MAX_CAD_NUMBER` (1e154) or more, whose square
  overflows (``1E+300``).

Measured on the shared 2-core machine: 1.3 s CPU for 55 MB of STEP (the seven NIST test parts
repeated), 0.05 s for the 3.4 MB ``nist_ctc_02``, 0.06 s for the hammer IGES; OpenCASCADE takes
minutes to import a 50 MB file.  (Not caught: a mantissa of more than 300 digits.)
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..errors import CADImportError

__all__ = ["check_numbers", "check_extent", "MAX_MODEL_COORDINATE", "MAX_CAD_NUMBER"]

#: Largest coordinate (mm) of a model accepted from a CAD file: 1e12 mm is a million km, as for
#: scans (:data:`shapeverify.io.points.MAX_COORDINATE`).
MAX_MODEL_COORDINATE = 1e12

_WORD = rb"(?:NAN|INF|INFINITY)"
# a real with a long exponent (E or D) | any D exponent | NaN/INF as a parameter | * beside a real
_STEP_BAD = re.compile(
    rb"(?<![A-Za-z0-9_#.])[+-]?\d+\.?\d*[EeDd][+-]?\d{3,}"
    rb"|(?<![A-Za-z0-9_#.])[+-]?\d+\.?\d*[Dd][+-]?\d+"
    rb"|(?<=[(,])\s*[+-]?" + _WORD + rb"\s*(?=[,)])"
    rb"|\d\.\d*(?:[Ee][+-]?\d+)?\s*,\s*\*(?=\s*[,)])"
    rb"|(?<=[(,])\s*\*\s*,\s*[+-]?\d+\.", re.IGNORECASE)
_IGES_BAD = re.compile(
    rb"(?<![A-Za-z0-9_.])[+-]?\d*\.?\d*[EeDd][+-]?\d{3,}"
    rb"|(?:^|(?<=[,;]))\s*[+-]?" + _WORD + rb"\s*(?=[,;])", re.IGNORECASE | re.MULTILINE)


def check_numbers(path, fmt: str, data: bytes | None = None) -> None:
    """Raise :class:`CADImportError` if a STEP/IGES file holds a number outside the float range.

    Parameters
    ----------
    path : str or Path
        The file (named in the message; read unless ``data`` is given).
    fmt : {"step", "iges"}
    data : bytes, optional
        The file's bytes, when the caller has them.

    Raises
    ------
    CADImportError
        The first bad token found: its line number and text.
    """
    path = Path(path)
    if data is None:
        data = path.read_bytes()
    if fmt == "step":
        bad = _step_bad(data)
    else:
        bad = _iges_bad(data)
    if bad is None:
        return
    pos, token = bad
    line = data.count(b"\n", 0, pos) + 1
    text = token.decode("latin-1").strip()
    raise CADImportError(
        f"{path}: line {line} holds {text!r}, which is {_what(text)} ({_why(text)}); "
        "OpenCASCADE cannot read such a value (it may never finish). The file is damaged or was "
        "written wrongly: export it again from the CAD system")


def _what(text: str) -> str:
    try:
        v = float(text.lstrip("+-").upper().replace("D", "E"))
    except ValueError:
        return "not a finite number"
    return "not a finite number" if not math.isfinite(v) or "D" in text.upper() else \
        "too large for any CAD number"


def _why(text: str) -> str:
    t = text.lstrip("+-").upper()
    if t.startswith(("NAN", "INF")):
        return "not a number"
    if "*" in t:
        return "a coordinate omitted with '*'"
    try:
        v = float(t.replace("D", "E"))
    except ValueError:
        return "not a number"
    if math.isinf(v):
        return "beyond the range of a double, about 1.8e308"
    if abs(v) >= MAX_CAD_NUMBER:
        return f"beyond +-{MAX_CAD_NUMBER:g}, where its square overflows a double"
    return "a Fortran 'D' exponent, which STEP does not allow"


def _candidates(data: bytes, start: int, step: bool):
    """Positions (in ``data``) near which a bad token may stand, found with numpy on chunks
    of the file with whitespace removed (a few vectorised passes; no Python loop per byte).

    A superset of the bad tokens' positions: each is confirmed by the regular expression."""
    n = len(data)
    arr = np.frombuffer(data, dtype=np.uint8)
    out = []
    pos = start
    while pos < n:
        end = min(n, pos + _CHUNK)
        # upper case, whitespace removed: bytes.translate runs at memory speed
        c = np.frombuffer(data[pos:min(n, end + _OVERLAP)].translate(_UPPER_TABLE, _SPACE),
                          dtype=np.uint8)
        m = c.size
        if m >= 8:
            c = np.concatenate([c, np.zeros(8, np.uint8)])  # a tail to look ahead into
            dig = (c >= 48) & (c <= 57)
            num = dig | (c == 46)
            sign = (c == 43) | (c == 45)
            ed = (c == 69) | (c == 68)
            d = c.astype(np.int16) - 48
            # an exponent of >= 3 digits with a value >= 150 (or >= 4 digits) starts at k
            big = dig[:-3] & dig[1:-2] & dig[2:-1] & ((d[:-3] * 100 + d[1:-2] * 10 + d[2:-1]
                                                        >= 150) | dig[3:])
            big = np.concatenate([big, np.zeros(3, bool)])
            after = big[1:] | (sign[1:] & np.concatenate([big[2:], [False]]))
            hit = np.zeros(c.size, bool)
            hit[1:-1] = ed[1:-1] & num[:-2] & after[1:]
            if step:  # any D exponent
                dnext = dig[1:] | (sign[1:] & np.concatenate([dig[2:], [False]]))
                hit[1:-1] |= (c[1:-1] == 68) & num[:-2] & dnext[1:]
                star = c == 42
                comma = c == 44
                # "real , *" or "* , real"
                hit[2:-2] |= star[2:-2] & ((comma[1:-3] & num[:-4])
                                           | (comma[3:-1] & (num[4:] | sign[4:])))
            nan = (c[:-2] == 78) & (c[1:-1] == 65) & (c[2:] == 78)
            inf = (c[:-2] == 73) & (c[1:-1] == 78) & (c[2:] == 70)
            hit[:-2] |= nan | inf
            k = np.flatnonzero(hit[:m])
            if k.size:  # back to positions in the file (only for a chunk with candidates)
                idx = np.flatnonzero(_KEEP[arr[pos:min(n, end + _OVERLAP)]])
                out.append(pos + idx[k])
        pos = end
    return np.unique(np.concatenate(out)) if out else np.zeros(0, np.int64)


def _step_bad(data: bytes):
    start = data.find(b"DATA;")
    start = 0 if start < 0 else start
    has_comments = data.find(b"/*", start) >= 0
    for p in _candidates(data, start, True):
        m = _STEP_BAD.search(data, max(start, int(p) - 64), int(p) + 64)
        while m is not None:
            tok = m.group(0)
            if not (_harmless_real(tok) or _in_string(data, start, m.start(), has_comments)):
                return m.start(), tok
            m = _STEP_BAD.search(data, m.end(), int(p) + 64)
    return None


#: Largest magnitude of a number accepted in a CAD file: beyond it the number's square overflows
#: a double (sqrt(1.8e308) = 1.34e154), and OpenCASCADE's geometry (distances, curve lengths)
#: goes to inf or never finishes: ``1E+300`` as a trimming curve's control point kept an IGES
#: import busy for over 120 s of CPU (CAD fuzz run, issue 33).  OpenCASCADE's own "infinite"
#: (``Precision::Infinite()``, 2e100) stays below it.
MAX_CAD_NUMBER = 1e154


def _harmless_real(tok: bytes) -> bool:
    """An E-exponent real with a long exponent whose square a double holds (e.g. ``1.E-400``
    -> 0, ``2.E+100``), not ``1.E+300``."""
    t = tok.strip()
    if b"*" in t or b"d" in t.lower():
        return False
    try:
        return abs(float(t)) < MAX_CAD_NUMBER
    except ValueError:
        return False


def _in_string(data: bytes, start: int, pos: int, has_comments: bool) -> bool:
    """Whether ``pos`` lies in a quoted STEP string (an odd number of quotes since the DATA
    section's start: ``''`` inside a string counts twice) or in a comment.  Called only for
    the rare hits of the token pattern; ``bytes.count`` runs at memory speed."""
    if has_comments:
        seg = re.sub(rb"/\*.*?\*/", b"", data[start:pos], flags=re.DOTALL)
        return b"/*" in seg or seg.count(b"'") % 2 == 1
    return data.count(b"'", start, pos) % 2 == 1


def _iges_bad(data: bytes):
    for p in _candidates(data, 0, False):
        p = int(p)
        ls = data.rfind(b"\n", 0, p) + 1
        le = data.find(b"\n", p)
        line = data[ls:le if le >= 0 else len(data)].rstrip(b"\r")
        if len(line) <= 72 or line[72:73] != b"P" or p - ls >= 64:
            continue  # not parameter data (a start, global or directory line)
        for m in _IGES_BAD.finditer(line[:64]):
            tok = m.group(0)
            if _harmless_real(tok.replace(b"D", b"E").replace(b"d", b"e")):
                continue
            return ls + m.start(), tok
    return None


_CHUNK = 1 << 23        # bytes per vectorised pass (bounds the temporary arrays to ~0.2 GB)
_OVERLAP = 256          # bytes shared by consecutive chunks (a token spans fewer)
_KEEP = np.ones(256, bool)
_KEEP[[9, 10, 11, 12, 13, 32]] = False
_SPACE = bytes([9, 10, 11, 12, 13, 32])
_UPPER_TABLE = bytes.maketrans(bytes(range(97, 123)), bytes(range(65, 91)))


def check_extent(path, lo, hi) -> None:
    """Raise :class:`CADImportError` if a model's bounding box (mm) is not finite or reaches
    beyond :data:`MAX_MODEL_COORDINATE`.

    A finite number that is absurd for a length (``1E+300`` in a control point: found by the CAD
    fuzz run, issue 33) passes :func:`check_numbers`; OpenCASCADE reads it, and the model's
    size overflows to ``inf`` (``info`` showed it, ``prepare`` failed with "spacing must be a
    finite number ... got inf", naming no file).
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        big = float(np.max(np.abs(np.concatenate([lo.ravel(), hi.ravel()]))))
        size = float(np.linalg.norm(hi - lo))
    if not (np.isfinite(big) and np.isfinite(size)) or big > MAX_MODEL_COORDINATE:
        raise CADImportError(
            f"{path}: the model reaches a coordinate of {big:.3g} mm, beyond +-"
            f"{MAX_MODEL_COORDINATE:g} mm (a million km): a damaged number in the file (a point "
            "or control point far out)? Export it again from the CAD system")
