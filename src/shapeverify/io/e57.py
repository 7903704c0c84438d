"""ASTM E57 files (E2807): the exchange format of laser and structured-light scanners.

An E57 file holds one or more scans, each in its own sensor frame with a *pose* that places it in
the file's common frame (a unit quaternion and a translation), in metres (the standard fixes the
unit). :func:`read_e57_views` returns each scan as a :class:`ScanView` in millimetres in the
common frame, with its pose; :func:`read_e57`, the reader that :func:`shapeverify.read_points`
uses for ``.e57``, returns all views' points together. Intensity and colour are ignored;
spherical scans (range, azimuth, elevation) are converted to Cartesian; points flagged invalid
are left out.

The file is decoded by libE57Format through ``pye57`` (the ``scanners`` extra:
``pip install 'shapeverify[scanners]'``). A damaged file raises
:class:`~shapeverify.errors.ScanError` naming it; a header that declares more points than the
file's bytes can hold is refused before anything is allocated.

Example
-------
>>> import numpy as np, tempfile, os
>>> from shapeverify.io.e57 import read_e57_views, write_e57
>>> path = os.path.join(tempfile.mkdtemp(), "two.e57")
>>> write_e57(path, [np.eye(3), 2 * np.eye(3)])     # points in mm, identity poses
>>> [v.points.shape for v in read_e57_views(path)]
[(3, 3), (3, 3)]
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapeverify.errors import ScanError, UnsupportedFormatError

__all__ = ["ScanView", "read_e57", "read_e57_views", "write_e57", "MAX_E57_POINTS"]

#: metres -> millimetres (E57 stores metres by the standard)
_MM_PER_M = 1000.0
#: The most points one file may declare in all (a billion points of float64 is 24 GB).
MAX_E57_POINTS = 400_000_000


@dataclass(frozen=True)
class ScanView:
    """One scan of a multi-scan file.

    Attributes
    ----------
    name : str
        The scan's name in the file (or ``"scan <i>"``).
    points : (N, 3) float64
        Its valid points in the file's common frame, mm.
    T_file_scan : (4, 4) float64
        Its pose: ``file_point = R @ scan_point + t`` (t in mm); identity when the file gives none.
    """

    name: str
    points: np.ndarray = field(repr=False)
    T_file_scan: np.ndarray = field(repr=False)

    def __repr__(self) -> str:
        return f"ScanView({self.name!r}, {len(self.points)} points)"


def _pye57(name: str):
    try:
        import pye57
    except ImportError:
        raise UnsupportedFormatError(
            f"{name}: reading E57 files needs pye57: pip install 'shapeverify[scanners]'") from None
    return pye57


def _rotation(q) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z), normalised (files round it)."""
    w, x, y, z = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _pose(header, name: str, i: int) -> np.ndarray:
    T = np.eye(4)
    if header.has_pose():
        node = header.node["pose"]
        q = [e.value() for e in node["rotation"]] if node.isDefined("rotation") else [1, 0, 0, 0]
        t = [e.value() for e in node["translation"]] if node.isDefined("translation") else [0, 0, 0]
        q, t = np.asarray(q, np.float64), np.asarray(t, np.float64)
        if q.shape != (4,) or t.shape != (3,) or not (np.isfinite(q).all() and np.isfinite(t).all()) \
                or np.linalg.norm(q) < 1e-6:
            raise ScanError(f"{name}: scan {i} has a malformed pose (rotation {q.tolist()}, "
                            f"translation {t.tolist()})")
        T[:3, :3] = _rotation(q)
        T[:3, 3] = t * _MM_PER_M
    return T


def _scan_name(header, i: int) -> str:
    try:
        return str(header.node["name"].value())
    except Exception:  # noqa: BLE001 - libE57's own exceptions: the name is optional
        return f"scan {i}"


def _xyz(data: dict, name: str, i: int) -> np.ndarray:
    if "cartesianX" in data:
        xyz = np.column_stack([data["cartesianX"], data["cartesianY"], data["cartesianZ"]])
    elif "sphericalRange" in data:
        r, az, el = (np.asarray(data[k], np.float64) for k in
                     ("sphericalRange", "sphericalAzimuth", "sphericalElevation"))
        xyz = np.column_stack([r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az),
                               r * np.sin(el)])
    else:
        raise ScanError(f"{name}: scan {i} has neither Cartesian nor spherical coordinates")
    return np.asarray(xyz, np.float64)


def _read_views(path: str, name: str, size: int) -> list[ScanView]:
    pye57 = _pye57(name)
    try:
        f = pye57.E57(path)
    except Exception as exc:  # noqa: BLE001 - libE57Format raises its own exception types
        raise ScanError(f"{name}: not a readable E57 file ({str(exc).splitlines()[0][:200]})") \
            from None
    views = []
    try:
        headers = [f.get_header(i) for i in range(f.scan_count)]
        declared = sum(int(h.point_count) for h in headers)
        # each point needs at least a bit of a varying coordinate: a count beyond 8 per byte of
        # file is a damaged or hostile header, refused before any buffer is allocated
        if declared > min(8 * size, MAX_E57_POINTS):
            raise ScanError(f"{name}: the file declares {declared} points in {size} bytes: "
                            "damaged header (or over the limit of "
                            f"{MAX_E57_POINTS} points per file)")
        for i, h in enumerate(headers):
            if int(h.point_count) == 0:
                continue
            data = f.read_scan(i, transform=False, ignore_missing_fields=True)
            xyz = _xyz(data, name, i) * _MM_PER_M
            T = _pose(h, name, i)
            views.append(ScanView(_scan_name(h, i), xyz @ T[:3, :3].T + T[:3, 3], T))
    except ScanError:
        raise
    except Exception as exc:  # noqa: BLE001 - libE57Format's checksum/structure errors
        raise ScanError(f"{name}: damaged E57 file ({str(exc).splitlines()[0][:200]})") from None
    finally:
        f.close()
    if not views:
        raise ScanError(f"{name}: the E57 file holds no points ({len(headers)} scans)")
    return views


def read_e57_views(source, name: str | None = None) -> list[ScanView]:
    """Each scan of an E57 file, in the file's common frame, mm.

    Parameters
    ----------
    source : str, os.PathLike or bytes
        The file, or its bytes.
    name : str, optional
        Stands for the file in messages (default: the path, or ``"<bytes>"``).

    Returns
    -------
    list of ScanView
        In file order; scans with no points are left out.

    Raises
    ------
    ScanError
        Not an E57 file, damaged (libE57Format checks every page's CRC), no points, a
        malformed pose, or more points declared than the file can hold.
    UnsupportedFormatError
        pye57 is not installed.
    """
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        return _read_views(str(path), str(path) if name is None else name, path.stat().st_size)
    data = bytes(source)
    with tempfile.TemporaryDirectory() as tmp:   # libE57Format reads files only
        p = os.path.join(tmp, "scan.e57")
        with open(p, "wb") as fh:
            fh.write(data)
        return _read_views(p, "<bytes>" if name is None else name, len(data))


def read_e57(data: bytes, name: str) -> np.ndarray:
    """All scans of an E57 file's bytes in its common frame, (N, 3) float64 mm (the
    :mod:`shapeverify.io.formats` reader for ``.e57``)."""
    return np.concatenate([v.points for v in read_e57_views(data, name)])


def write_e57(path, views, poses=None) -> None:
    """Write scans (each (N, 3) mm, in its own frame) to an E57 file, with optional poses
    ``T_file_scan`` ((4, 4), translation in mm). For tests and for exporting views."""
    pye57 = _pye57(str(path))
    from scipy.spatial.transform import Rotation

    f = pye57.E57(str(path), mode="w")
    try:
        for i, pts in enumerate(views):
            pts = np.asarray(pts, np.float64) / _MM_PER_M
            T = np.eye(4) if poses is None else np.asarray(poses[i], np.float64)
            x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
            f.write_scan_raw({"cartesianX": pts[:, 0], "cartesianY": pts[:, 1],
                              "cartesianZ": pts[:, 2]}, name=f"scan {i}",
                             rotation=np.array([w, x, y, z]), translation=T[:3, 3] / _MM_PER_M)
    finally:
        f.close()
