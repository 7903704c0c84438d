"""NumPy ``.npy`` files, read without pickle and without trusting the header.

:func:`read_npy` reads scans: an ``(N, 3)`` or ``(N, >=3)`` numeric array (first three
columns), or a structured array with fields ``x y z``.  :func:`load_npy` reads any numeric
``.npy`` (phase maps, poses) the same careful way.

The header is checked against the file before anything is allocated: the data must be exactly
as long as the header's shape and dtype say -- a header that promises more than the file holds
(a ``(10**10, 3)`` array in a 200-byte file) and data with bytes inserted or appended (which
would shift every value after them) are both refused with the declared and the found size.

>>> import io, numpy as np
>>> buf = io.BytesIO(); np.save(buf, np.arange(6.0).reshape(2, 3))
>>> load_npy(buf.getvalue(), "a.npy").tolist()
[[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]
>>> load_npy(buf.getvalue() + b"\\0" * 8, "a.npy")
Traceback (most recent call last):
    ...
shapeverify.errors.ScanError: a.npy: the .npy header declares shape (2, 3) of float64 (48 bytes of data), the file holds 56 bytes: bytes were inserted or appended (or the header was edited); save the array again with numpy.save
"""

from __future__ import annotations

import io
import os
import tokenize
from pathlib import Path

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["read_npy", "load_npy", "npy_layout"]

_HEADER_ERRORS = (ValueError, OSError, EOFError, SyntaxError, TypeError, RecursionError,
                  MemoryError, OverflowError, tokenize.TokenError)


def npy_layout(data: bytes, name: str, error=ScanError):
    """``(shape, fortran_order, dtype, offset)`` of a ``.npy`` file's bytes, after checking that
    the data after the header is exactly as long as the header says.

    Raises
    ------
    error (default ScanError)
        Not a ``.npy`` file, a malformed header, Python objects (pickle), or data whose length
        is not the declared one.
    """
    fmt = np.lib.format
    try:
        with io.BytesIO(data) as fh:
            major, _ = fmt.read_magic(fh)
            if major == 1:
                shape, fortran, dtype = fmt.read_array_header_1_0(fh)
            elif major in (2, 3):
                shape, fortran, dtype = fmt.read_array_header_2_0(fh)
            else:
                raise ValueError(f"unknown .npy format version {major}")
            offset = fh.tell()
    except _HEADER_ERRORS as exc:  # numpy parses the header with tokenize + ast
        raise error(f"{name}: not a readable .npy array ({str(exc)[:200]})") from None
    if dtype.hasobject:
        raise error(f"{name}: .npy holds Python objects; save a numeric array instead")
    if dtype.itemsize == 0:
        raise error(f"{name}: .npy dtype {dtype} has items of 0 bytes; save a numeric array")
    if any(int(n) < 0 for n in shape):
        raise error(f"{name}: malformed .npy header: negative shape {shape}")
    count = 1
    for n in shape:
        count *= int(n)
    need, body = count * dtype.itemsize, len(data) - offset
    if need > body:
        raise error(f"{name}: truncated .npy: header declares shape {shape} of {dtype} "
                    f"({need} bytes), the file holds {body} bytes of data")
    if need < body:
        raise error(f"{name}: the .npy header declares shape {shape} of {dtype} ({need} bytes of "
                    f"data), the file holds {body} bytes: bytes were inserted or appended (or "
                    "the header was edited); save the array again with numpy.save")
    return shape, fortran, dtype, offset


def load_npy(source, name: str | None = None, error=ScanError) -> np.ndarray:
    """The array of a ``.npy`` file (a path or its bytes), any shape, checked as
    :func:`npy_layout` says; nothing larger than the file is allocated.

    Parameters
    ----------
    source : str, os.PathLike or bytes
    name : str, optional
        Stands for the file in messages (default: the path).
    error : type
        The exception class raised for a bad file (default :class:`ScanError`; callers that
        promise ``ValueError`` may pass it).
    """
    if isinstance(source, (str, os.PathLike)):
        name = str(source) if name is None else name
        data = Path(source).read_bytes()
    else:
        data, name = bytes(source), ("<bytes>" if name is None else name)
    shape, fortran, dtype, offset = npy_layout(data, name, error)
    count = 1
    for n in shape:
        count *= int(n)
    arr = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
    return arr.reshape(shape, order="F" if fortran else "C").copy(order="K")


def read_npy(data: bytes, name: str) -> np.ndarray:
    """The first three columns (or fields ``x y z``) of a ``.npy`` file's bytes, (N, 3) float64."""
    arr = load_npy(data, name)
    if arr.dtype.names:
        if not all(c in arr.dtype.names for c in "xyz"):
            raise ScanError(f"{name}: structured array without fields x, y, z "
                            f"(fields: {', '.join(arr.dtype.names)})")
        try:
            arr = np.column_stack([arr[c].ravel().astype(np.float64) for c in "xyz"])
        except (ValueError, TypeError) as exc:
            raise ScanError(f"{name}: fields x, y, z are not numeric scalars ({exc})") from None
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise ScanError(f"{name}: array dtype {arr.dtype} is not numeric")
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise ScanError(f"{name}: array has shape {arr.shape}; expected (N, 3) or (N, >=3)")
    if arr.shape[0] == 0:
        raise ScanError(f"{name}: contains no points (shape {arr.shape})")
    with np.errstate(invalid="ignore", over="ignore"):   # NaN/inf are dropped and reported later
        return np.asarray(arr[:, :3], dtype=np.float64)
