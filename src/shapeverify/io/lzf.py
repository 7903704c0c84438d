"""LZF decompression (liblzf's format, as PCL's ``DATA binary_compressed`` uses it), checked.

Nothing is trusted: the output may not exceed the size the caller expects (and is allocated only
once that size is known to be reachable from the input: LZF expands at most ~ 132 times), a back
reference may not point before the start of the output, the input may not end inside a token, and
the output must have exactly the expected length.

>>> lzf_decompress(bytes([2]) + b"abc" + bytes([0x20 | 0, 2]), 6, "x")   # "abc" + copy of 3
b'abcabc'
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shapeverify.errors import ScanError

__all__ = ["lzf_decompress", "MAX_RATIO"]

#: The largest ratio of output to input LZF can reach (a 3-byte token copies 264 bytes).
MAX_RATIO = 132


def lzf_decompress(src: bytes, expected: int, name: str) -> bytes:
    """The ``expected`` bytes that the LZF stream ``src`` decodes to.

    Raises
    ------
    ScanError
        ``expected`` out of reach of ``src``'s size, a damaged stream (a back reference before
        the start, a token cut off), or an output of another length than ``expected``.
    """
    if expected < 0 or expected > MAX_RATIO * len(src) + 64:
        raise ScanError(f"{name}: the compressed data ({len(src)} bytes) cannot decode to the "
                        f"{expected} bytes the header declares; the file is damaged")
    out = np.empty(expected, np.uint8)
    status, i, o = _decode(np.frombuffer(src, np.uint8), out)
    if status:
        raise ScanError(f"{name}: the compressed point data is damaged (LZF stream broken at "
                        f"byte {i} of {len(src)}); save the cloud again or as DATA binary")
    if o != expected:
        raise ScanError(f"{name}: the compressed point data decodes to {o} bytes, the header "
                        f"declares {expected}; the file is damaged")
    return out.tobytes()


@njit(cache=True, nogil=True)
def _decode(src, out):
    """LZF-decode ``src`` into ``out``; ``(status, input position, output length)`` with status
    0 (complete input read) or 1 (damaged: a token cut off, a reference before the start, more
    output than ``out`` holds)."""
    n, m = src.size, out.size
    i = o = 0
    while i < n:
        c = np.int64(src[i])
        i += 1
        if c < 32:                          # a run of c + 1 literal bytes
            k = c + 1
            if i + k > n or o + k > m:
                return 1, i, o
            out[o:o + k] = src[i:i + k]
            i += k
            o += k
            continue
        k = c >> 5                          # a back reference of k + 2 bytes
        if k == 7:
            if i >= n:
                return 1, i, o
            k += np.int64(src[i])
            i += 1
        if i >= n:
            return 1, i, o
        ref = o - ((c & 0x1F) << 8) - np.int64(src[i]) - 1
        i += 1
        k += 2
        if ref < 0 or o + k > m:
            return 1, i, o
        for j in range(k):                  # byte by byte: overlapping copies repeat
            out[o + j] = out[ref + j]
        o += k
    return 0, i, o
