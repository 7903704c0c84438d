"""The format of an uploaded request body: its content type or a sniff of its first bytes.

The points themselves are read by :func:`shapeverify.io.points.read_points` from the bytes
(:func:`shapeverify.pipeline.inspect_scan` does that for ``POST /inspect``).
"""

from __future__ import annotations

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError
from shapeverify.io.formats import SCAN_CONTENT_TYPES, scan_families, sniff_scan
from shapeverify.io.formats import scan_format as _by_suffix

#: What the service accepts, in words (the 415 answers): every format of the registry.
SUPPORTED = "a scan file: " + ", ".join(f"{family} ({' '.join(suffixes)})"
                                         for family, suffixes in scan_families().items())
#: content types that say nothing about the format: the first bytes decide
#: (curl --data-binary sends application/x-www-form-urlencoded unless told otherwise)
_SNIFFED_TYPES = ("text/plain", "application/octet-stream", "application/x-www-form-urlencoded")
#: Every content type ``POST /inspect`` documents: the registry's and the sniffed ones.
SCAN_TYPES = ["application/octet-stream", *SCAN_CONTENT_TYPES, "text/plain"]


def sniff_suffix(body: bytes, content_type: str | None = None) -> str:
    """Return the file suffix for ``body``.

    An explicit content type of a registered format wins
    (:data:`shapeverify.io.formats.SCAN_CONTENT_TYPES`); ``application/octet-stream``,
    ``text/plain``, ``application/x-www-form-urlencoded`` (curl's default) and a missing type
    fall back to the registry's sniffing of the first bytes
    (:func:`shapeverify.io.formats.sniff_scan`). A text body with numbers (or NaN/inf) is an
    XYZ/CSV table, so that a NaN-only table is reported as a bad scan (422), not as an unknown
    format.

    Raises
    ------
    UnsupportedFormatError
        When the body is none of the supported formats.
    """
    ctype = (content_type or "").split(";")[0].strip().lower()
    if ctype in SCAN_CONTENT_TYPES:
        return SCAN_CONTENT_TYPES[ctype]
    fmt = sniff_scan(body)
    if fmt is not None:
        return fmt.suffix
    head = body[:512]
    if any(b < 32 and b not in b"\t\n\r\f\v" for b in head) or b"\x7f" in head:
        binary = [fam for fam, sfx in scan_families().items() if _by_suffix(sfx[0]).magic]
        raise UnsupportedFormatError(
            f"the request body is binary but not {', '.join(binary)} (first bytes {head[:8]!r}); "
            f"send {SUPPORTED}")
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
