"""The width and height of an image from its header, before anything is decoded.

An 875 KB PNG can decode to 30,000 x 30,000 pixels (1.9 GB); decoders (OpenCV, Pillow) allocate
the whole image before a caller can look at its size.  :func:`image_size` reads the size from
the first bytes of the file -- PNG (IHDR), TIFF and BigTIFF (first page's ImageWidth and
ImageLength), JPEG (the SOF segment), BMP, PNM -- and, for other formats, from Pillow's lazy
``Image.open`` (which parses the header only).  :func:`check_image_size` refuses an image whose
header declares more pixels than a limit, or another size than the one expected.

>>> import struct, zlib
>>> ihdr = struct.pack(">IIBBBBB", 30000, 30000, 8, 0, 0, 0, 0)
>>> png = (b"\\x89PNG\\r\\n\\x1a\\n" + struct.pack(">I", 13) + b"IHDR" + ihdr
...        + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)))
>>> image_size(png)
(30000, 30000, 'PNG')
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

from shapeverify.errors import ShapeVerifyError

__all__ = ["ImageInputError", "image_size", "check_image_size", "MAX_IMAGE_PIXELS"]

#: Most pixels an image file may declare (200 million: above every camera the optical chain
#: uses -- 151 MP sensors exist -- and far below what a crafted header can ask for).
MAX_IMAGE_PIXELS = 200_000_000
_HEAD = 1 << 16   # the bytes read for the header (a JPEG's SOF may follow large EXIF segments)


class ImageInputError(ShapeVerifyError, ValueError):
    """An image file that cannot be read safely: unknown format, or a size beyond the limit."""


def image_size(source) -> tuple[int, int, str] | None:
    """``(width, height, format)`` from an image file's header (a path or its first bytes),
    or None when the header is not one of the formats read here (nor Pillow's)."""
    if isinstance(source, (str, os.PathLike)):
        with open(source, "rb") as fh:
            head = fh.read(_HEAD)
    else:
        head = bytes(source[:_HEAD])
    for probe in (_png, _tiff, _jpeg, _bmp, _pnm):
        try:
            got = probe(head)
        except (struct.error, ValueError, IndexError):
            got = None
        if got is not None:
            return got
    if isinstance(source, (str, os.PathLike)):
        return _pillow(source)
    return None


def check_image_size(path, expected=None, max_pixels: int = MAX_IMAGE_PIXELS,
                     what: str = "image") -> tuple[int, int]:
    """The ``(width, height)`` an image file's header declares, after checking it.

    Parameters
    ----------
    path : str or os.PathLike
    expected : (int, int), optional
        The size it must have (a camera's ``(width, height)``).
    max_pixels : int
        The most pixels accepted.
    what : str
        Names the image in messages (``"left image"``).

    Raises
    ------
    ImageInputError
        An unknown format, a size other than ``expected``, or more than ``max_pixels`` pixels;
        the message names the file, the size and the limit.
    """
    got = image_size(path)
    if got is None:
        raise ImageInputError(f"{path}: the {what} is not a PNG, TIFF, JPEG, BMP or PNM image "
                              "(its header was not recognised); save it as PNG or TIFF")
    w, h, kind = got
    if expected is not None and (w, h) != tuple(int(x) for x in expected):
        raise ImageInputError(f"{path}: the {what} is {w} x {h} pixels (W x H, from its {kind} "
                              f"header), the camera is {expected[0]} x {expected[1]}: give the "
                              "image this camera took (or the rig of the camera that took it)")
    if w * h > max_pixels or w < 1 or h < 1:
        raise ImageInputError(f"{path}: the {what} declares {w} x {h} pixels in its {kind} header "
                              f"({w * h:,} pixels; the limit is {max_pixels:,}): refused before "
                              "decoding it; the file is damaged, or not a camera image")
    return w, h


def _png(b: bytes):
    if b[:8] != b"\x89PNG\r\n\x1a\n" or b[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", b[16:24])
    return w, h, "PNG"


def _tiff(b: bytes):
    if b[:4] in (b"II*\0", b"MM\0*"):
        e = "<" if b[:2] == b"II" else ">"
        big, off = False, struct.unpack(e + "I", b[4:8])[0]
    elif b[:4] in (b"II+\0", b"MM\0+"):
        e = "<" if b[:2] == b"II" else ">"
        big, off = True, struct.unpack(e + "Q", b[8:16])[0]
    else:
        return None
    n = struct.unpack(e + ("Q" if big else "H"), b[off: off + (8 if big else 2)])[0]
    pos, size = off + (8 if big else 2), (20 if big else 12)
    found = {}
    for i in range(min(n, 4096)):
        entry = b[pos + i * size: pos + (i + 1) * size]
        if len(entry) < size:
            break
        tag, typ = struct.unpack(e + "HH", entry[:4])
        if tag not in (256, 257):
            continue
        value = entry[12:] if big else entry[8:]
        code = {3: "H", 4: "I", 16: "Q"}.get(typ)
        if code is None:
            raise ValueError("unsupported TIFF size type")
        found[tag] = struct.unpack(e + code, value[:struct.calcsize(code)])[0]
    if 256 in found and 257 in found:
        return found[256], found[257], "TIFF"
    raise ValueError("TIFF without ImageWidth/ImageLength in the first IFD")


def _jpeg(b: bytes):
    if b[:2] != b"\xff\xd8":
        return None
    pos = 2
    while pos + 4 <= len(b):
        if b[pos] != 0xFF:
            return None
        marker = b[pos + 1]
        if marker == 0xFF:   # fill byte
            pos += 1
            continue
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        if marker in (0xD9, 0xDA):   # end of image, start of scan: no frame header before
            return None
        length = struct.unpack(">H", b[pos + 2: pos + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", b[pos + 5: pos + 9])
            return w, h, "JPEG"
        pos += 2 + length
    return None


def _bmp(b: bytes):
    if b[:2] != b"BM" or len(b) < 26:
        return None
    hsize = struct.unpack("<I", b[14:18])[0]
    if hsize == 12:
        w, h = struct.unpack("<HH", b[18:22])
    else:
        w, h = struct.unpack("<ii", b[18:26])
    return abs(w), abs(h), "BMP"


def _pnm(b: bytes):
    if len(b) < 3 or b[0:1] != b"P" or b[1:2] not in b"123456":
        return None
    tokens, i = [], 2
    while len(tokens) < 2 and i < len(b):
        c = b[i:i + 1]
        if c == b"#":
            i = b.find(b"\n", i)
            if i < 0:
                return None
        elif c.isspace():
            i += 1
        else:
            j = i
            while j < len(b) and not b[j:j + 1].isspace() and j - i < 12:
                j += 1
            if not b[i:j].isdigit():
                return None
            tokens.append(int(b[i:j]))
            i = j
    if len(tokens) < 2:
        return None
    return tokens[0], tokens[1], "PNM"


def _pillow(path):
    try:
        import warnings

        from PIL import Image
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(Path(path)) as im:   # lazy: parses the header only
                return int(im.size[0]), int(im.size[1]), str(im.format or "image")
    except Exception:  # noqa: BLE001 - Pillow raises many types for files it does not know
        return None
