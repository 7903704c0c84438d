"""The format of an uploaded request body: its content type or a sniff of its first bytes.

The points themselves are read by :func:`shapeverify.io.points.read_points` from the bytes
(:func:`shapeverify.pipeline.inspect_scan` does that for ``POST /inspect``).
"""

from __future__ import annotations

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError

# content type -> file suffix understood by shapeverify.io.points.read_points
_CONTENT_TYPES = {
    "application/x-npy": ".npy",
    "application/npy": ".npy",
    "application/ply": ".ply",
    "model/ply": ".ply",
    "application/x-ply": ".ply",
    "text/x-xyz": ".xyz",
    "text/csv": ".csv",
    "application/x-pcd": ".pcd",
    "application/x-e57": ".e57",
    "application/vnd.las": ".las",
    "application/vnd.laszip": ".laz",
}
SUPPORTED = "PLY (ascii or binary), NPY, PCD, E57, LAS/LAZ, or XYZ/CSV text"
# content types that say nothing about the format: the first bytes decide
# (curl --data-binary sends application/x-www-form-urlencoded unless told otherwise)
_SNIFFED_TYPES = ("text/plain", "application/octet-stream", "application/x-www-form-urlencoded")


def sniff_suffix(body: bytes, content_type: str | None = None) -> str:
    """Return the file suffix for ``body``.

    An explicit, known content type wins; ``application/octet-stream``, ``text/plain``,
    ``application/x-www-form-urlencoded`` (curl's default) and a missing type fall back to
    sniffing the first bytes. A text body with numbers (or NaN/inf) is an XYZ/CSV table, so that a
    NaN-only table is reported as a bad scan (422), not as an unknown format.

    Raises
    ------
    UnsupportedFormatError
        When the body is none of the supported formats.
    """
    ctype = (content_type or "").split(";")[0].strip().lower()
    if ctype in _CONTENT_TYPES:
        return _CONTENT_TYPES[ctype]
    head = body[:512]
    if head.startswith(b"ply"):
        return ".ply"
    if head.startswith(b"\x93NUMPY"):
        return ".npy"
    if head.lstrip().startswith((b"# .PCD", b"VERSION", b"FIELDS")):
        return ".pcd"
    if head.startswith(b"ASTM-E57"):
        return ".e57"
    if head.startswith(b"LASF"):   # LAS or LAZ: laspy tells them apart from the header
        return ".las"
    if any(b < 32 and b not in b"\t\n\r\f\v" for b in head) or b"\x7f" in head:
        raise UnsupportedFormatError(
            f"the request body is binary but not PLY, NPY, PCD, E57 or LAS (first bytes {head[:8]!r}); send {SUPPORTED}")
    text = head.decode("latin-1")
    if ctype.startswith("multipart/"):
        raise UnsupportedFormatError(
            "multipart form uploads are not accepted: send the scan file itself as the request body "
            f"(e.g. curl --data-binary @scan.ply); {SUPPORTED}")
    if ctype and ctype not in _SNIFFED_TYPES:
        raise UnsupportedFormatError(f"unsupported content type {ctype!r}; send {SUPPORTED}")
    low = text.lower()
    if not any(ch.isdigit() for ch in text) and "nan" not in low and "inf" not in low:
        raise UnsupportedFormatError(f"the request body is text without numbers; send {SUPPORTED}")
    first = next((ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), "")
    return ".csv" if "," in first else ".xyz"


def body_format(body: bytes, content_type: str | None = None, name: str = "request body") -> str:
    """The scan format (file suffix) of an upload: :func:`sniff_suffix`, after refusing an
    empty body.

    Raises
    ------
    ScanError
        An empty body.
    UnsupportedFormatError
        Not a supported format.
    """
    if not body:
        raise ScanError(f"{name}: empty; send the scan points as " + SUPPORTED)
    return sniff_suffix(body, content_type)


def parse_scan(body: bytes, content_type: str | None = None, name: str = "request body") -> np.ndarray:
    """Parse a scan upload into (N, 3) float64 points (mm), in memory.

    ``name`` stands for the data in error messages.

    Raises
    ------
    ScanError
        Empty, malformed, or without a single finite point.
    UnsupportedFormatError
        Not a supported format.
    """
    from shapeverify.io.points import read_points

    return read_points(body, body_format(body, content_type, name), name=name)
