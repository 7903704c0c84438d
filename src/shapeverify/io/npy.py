"""NumPy ``.npy`` scans: an ``(N, 3)`` or ``(N, >=3)`` numeric array (first three columns), or a
structured array with fields ``x y z``.  Loaded without pickle; a header that promises more data
than the file holds is refused before numpy allocates it.
"""

from __future__ import annotations

import io
import tokenize

import numpy as np

from shapeverify.errors import ScanError

__all__ = ["read_npy"]


def _check_npy_size(data: bytes, name: str) -> None:
    """Refuse a .npy whose header promises more data than the file holds (before numpy
    allocates an array of the promised size)."""
    fmt = np.lib.format
    with io.BytesIO(data) as fh:
        major, _ = fmt.read_magic(fh)
        read_header = fmt.read_array_header_1_0 if major == 1 else fmt.read_array_header_2_0
        shape, _, dtype = read_header(fh)
        body = len(data) - fh.tell()
    if dtype.hasobject:
        raise ScanError(f"{name}: .npy holds Python objects; save a numeric array instead")
    count = 1
    for n in shape:
        count *= int(n)
    if count * dtype.itemsize > body:
        raise ScanError(f"{name}: truncated .npy: header declares shape {shape} of {dtype} "
                        f"({count * dtype.itemsize} bytes), the file holds {body} bytes of data")


def read_npy(data: bytes, name: str) -> np.ndarray:
    """The first three columns (or fields ``x y z``) of a ``.npy`` file's bytes, (N, 3) float64."""
    try:
        _check_npy_size(data, name)
        arr = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError, SyntaxError, TypeError, RecursionError,
            tokenize.TokenError) as exc:  # numpy parses the header with tokenize + ast
        if isinstance(exc, ScanError):
            raise
        raise ScanError(f"{name}: not a readable .npy array ({exc})") from None
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
