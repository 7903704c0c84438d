"""ASPRS LAS (and LAZ) point clouds: the ``x y z`` of every point record, scaled and offset as
the header says, in the file's own unit (LAS declares its unit only through an optional
coordinate reference system; give the scan's unit with ``--scan-unit`` when it is not mm).

Read with ``laspy`` (the ``scanners`` extra: ``pip install 'shapeverify[scanners]'``; LAZ also
needs a LAZ backend: ``pip install 'laspy[lazrs]'``). A header whose point count disagrees with
the bytes the file holds is an error, never a silent truncation.

Example
-------
>>> import io, numpy as np, laspy
>>> from shapeverify.io.las import read_las
>>> las = laspy.create(point_format=0, file_version="1.2")
>>> las.header.scales = [0.001] * 3
>>> las.x, las.y, las.z = [0.0, 1.5], [2.0, 2.5], [3.0, 0.25]
>>> buf = io.BytesIO(); las.write(buf)
>>> read_las(buf.getvalue(), "two.las").tolist()
[[0.0, 2.0, 3.0], [1.5, 2.5, 0.25]]
"""

from __future__ import annotations

import io
import struct

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError

__all__ = ["read_las"]


def read_las(data: bytes, name: str) -> np.ndarray:
    """The points of a LAS/LAZ file's bytes, (N, 3) float64 as stored (scale and offset applied)."""
    try:
        import laspy
    except ImportError:
        raise UnsupportedFormatError(
            f"{name}: reading LAS/LAZ files needs laspy: pip install 'shapeverify[scanners]'") \
            from None
    _check_header(data, name)
    try:
        with laspy.open(io.BytesIO(data)) as reader:
            hdr = reader.header
            n = int(hdr.point_count)
            compressed = bool(getattr(hdr, "are_points_compressed", False))
            if n == 0:
                raise ScanError(f"{name}: the LAS file holds no points (point count 0)")
            if not compressed:
                need = int(hdr.offset_to_point_data) + n * int(hdr.point_format.size)
                if need > len(data):
                    raise ScanError(f"{name}: truncated LAS file: the header declares {n} points "
                                    f"({need} bytes with the header), the file has {len(data)}")
            elif n > 64 * len(data):   # LAZ compresses a point to a few bytes, never to 1/64 byte
                raise ScanError(f"{name}: the LAZ header declares {n} points in {len(data)} "
                                "bytes: damaged header")
            pts = reader.read_points(n)
    except ScanError:
        raise
    except laspy.errors.LaspyException as exc:
        msg = str(exc)
        if "backend" in msg.lower() or "laz" in msg.lower() and "support" in msg.lower():
            raise UnsupportedFormatError(f"{name}: {msg}; pip install 'laspy[lazrs]'") from None
        raise ScanError(f"{name}: not a readable LAS file ({msg[:200]})") from None
    except (ValueError, OSError, EOFError, IndexError, KeyError, TypeError, OverflowError,
            MemoryError, struct.error) as exc:
        raise ScanError(f"{name}: damaged LAS file ({type(exc).__name__}: {str(exc)[:200]})") \
            from None
    if len(pts) != n:
        raise ScanError(f"{name}: the LAS header declares {n} points, the file holds {len(pts)}")
    return np.column_stack([np.asarray(pts.x, np.float64), np.asarray(pts.y, np.float64),
                            np.asarray(pts.z, np.float64)])


#: Bytes of a LAS variable-length record's header (ASPRS LAS 1.0-1.4).
_VLR_HEADER = 54


def _check_header(data: bytes, name: str) -> None:
    """Refuse a LAS header whose counts the file cannot hold, before laspy reads it.

    A damaged count of variable-length records (``0xFF...`` in bytes 100-103) had laspy read
    billions of records from a 1 kB file for minutes (found by the reader fuzz test); each
    record takes at least 54 bytes, so the count is bounded by the bytes before the points."""
    if len(data) < 107 or data[:4] != b"LASF":
        return                                   # laspy names what is wrong
    header_size, offset, n_vlr = struct.unpack_from("<HIL", data, 94)
    room = min(offset, len(data)) - header_size
    if n_vlr and n_vlr * _VLR_HEADER > max(room, 0):
        raise ScanError(f"{name}: damaged LAS header: it declares {n_vlr} variable-length "
                        f"records, the {max(room, 0)} bytes between the header and the points "
                        f"hold at most {max(room, 0) // _VLR_HEADER}")
