"""One round-trip suite over the scan format registry (issue 31 items 4 and 6).

Every :class:`shapeverify.io.formats.ScanFormat` of :data:`~shapeverify.io.formats.SCAN_FORMATS`
is written by a second library (open3d, trimesh, pye57, laspy, numpy, Python's csv) -- never by
shapeverify's own writers -- and read back through the registry: the points come back exactly
(bit for bit for the formats that store float64; to the stored quantum for LAS's scaled integers
and float32 STL, whose points are chosen representable).  A registered format without a writer
here fails :func:`test_every_registered_format_has_a_round_trip`: adding a format means adding
its writer.  The registry is also what the service sniffs and the CLI lists.
"""

from __future__ import annotations

import csv
import io
import os

import numpy as np
import pytest

from shapeverify.io.formats import (SCAN_CONTENT_TYPES, SCAN_FORMATS, SCAN_SUFFIXES, scan_format,
                                    scan_help, sniff_scan)
from shapeverify.io.points import read_points


def _points(rng, n=200) -> np.ndarray:
    """float64 points with full mantissas (a text writer that rounds would be caught)."""
    return rng.normal(0.0, 40.0, (n, 3))


def _grid_mesh():
    """An even triangle grid with coordinates exact in float32 (STL stores float32): its scan
    points are its vertices (:mod:`shapeverify.io.mesh_scan`)."""
    x, y = np.meshgrid(np.arange(6) * 2.5, np.arange(5) * 2.5, indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), 0.25 * (x.ravel() + y.ravel())])
    idx = np.arange(v.shape[0]).reshape(6, 5)
    tri = []
    for i in range(5):
        for j in range(4):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            tri += [[a, b, c], [a, c, d]]
    return v, np.array(tri)


def _w_text(sep):
    def write(path, rng):          # a header, a comment and a NaN row (dropped by read_points)
        p = _points(rng)
        rows = np.vstack([p[:100], [np.nan, 1.0, 2.0], p[100:]])
        np.savetxt(path, rows, fmt="%.17g", delimiter=sep, header=sep.join("xyz") + "\n a comment",
                   comments="")
        text = path.read_text().replace("\n a comment", "\n# a comment")
        path.write_text(text)
        return p, False
    return write


def _w_csv(path, rng):
    p = _points(rng)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["x", "y", "z"])
        w.writerows([[repr(float(c)) for c in row] for row in p])
    return p, False


def _w_npy(path, rng):
    p = _points(rng)
    np.save(path, p)
    return p, False


def _w_open3d(path, rng):
    o3d = pytest.importorskip("open3d")
    p = _points(rng)
    if path.suffix == ".pcd":            # open3d's PCD stores float32: points that it holds
        p = p.astype(np.float32).astype(np.float64)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    assert o3d.io.write_point_cloud(str(path), pc, write_ascii=False)
    return p, False


def _w_e57(path, rng):
    pye57 = pytest.importorskip("pye57")
    # E57 stores metres; pye57's raw writer stores single precision: points that it holds
    m = (_points(rng) / 1000.0).astype(np.float32).astype(np.float64)
    f = pye57.E57(str(path), mode="w")
    f.write_scan_raw({"cartesianX": m[:, 0], "cartesianY": m[:, 1], "cartesianZ": m[:, 2]})
    f.close()
    return m * 1000.0, False                       # read in mm


def _w_las(compressed):
    def write(path, rng):
        laspy = pytest.importorskip("laspy")
        if compressed:
            pytest.importorskip("lazrs")
        q = rng.integers(-50_000, 50_000, (200, 3))
        hdr = laspy.LasHeader(point_format=0, version="1.2")
        hdr.scales = np.array([0.001, 0.001, 0.001])
        hdr.offsets = np.array([10.0, -20.0, 5.0])
        las = laspy.LasData(hdr)
        las.X, las.Y, las.Z = q[:, 0], q[:, 1], q[:, 2]
        las.write(str(path))
        return q * 0.001 + hdr.offsets, "quantum"
    return write


def _w_trimesh(path, rng):
    trimesh = pytest.importorskip("trimesh")
    v, t = _grid_mesh()
    trimesh.Trimesh(v, t, process=False).export(str(path))
    return v, True                                  # a mesh: compared as a set of rows


#: suffix -> writer(path, rng) -> (expected points, how to compare)
WRITERS = {".ply": _w_open3d, ".xyz": _w_text(" "), ".txt": _w_text("\t"), ".csv": _w_csv,
           ".npy": _w_npy, ".pcd": _w_open3d, ".e57": _w_e57, ".las": _w_las(False),
           ".laz": _w_las(True), ".stl": _w_trimesh, ".obj": _w_trimesh}


def test_every_registered_format_has_a_round_trip():
    assert set(WRITERS) == set(SCAN_SUFFIXES)


@pytest.mark.parametrize("fmt", SCAN_FORMATS, ids=lambda f: f.suffix)
def test_registered_reader_reads_back_what_a_second_library_wrote(fmt, tmp_path):
    rng = np.random.default_rng(SCAN_SUFFIXES.index(fmt.suffix))
    path = tmp_path / f"scan{fmt.suffix}"
    expected, how = WRITERS[fmt.suffix](path, rng)
    got = read_points(path)                              # through the registry, by suffix
    assert got.dtype == np.float64 and got.shape == expected.shape
    data = path.read_bytes()
    raw = fmt.read(data, str(path))      # the row's reader is read_points' (which drops NaN rows)
    assert np.array_equal(raw[np.isfinite(raw).all(axis=1)], got)
    # the same points from the bytes, a bytearray, a file object (format given or from its name)
    assert np.array_equal(read_points(data, fmt.suffix), got)
    assert np.array_equal(read_points(bytearray(data), fmt.suffix.lstrip(".").upper()), got)
    assert np.array_equal(read_points(io.BytesIO(data), fmt.suffix), got)
    with open(path, "rb") as fh:
        assert np.array_equal(read_points(fh), got)
    if how is True:                                      # a mesh: the same rows, any order
        assert np.array_equal(np.unique(got, axis=0), np.unique(expected, axis=0))
    elif how == "quantum":
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    else:
        assert np.array_equal(got, expected)
    # what the content says it is: this format (or, for text, nothing: the suffix decides)
    sniffed = sniff_scan(data)
    if fmt.magic:
        assert sniffed is not None and sniffed.family == fmt.family, sniffed
    else:
        assert sniffed is None


@pytest.mark.parametrize("fmt", [f for f in SCAN_FORMATS if f.content_types],
                         ids=lambda f: f.suffix)
def test_service_reads_every_content_type_of_the_registry(fmt, tmp_path):
    from shapeverify.service.body import sniff_suffix

    for ctype in fmt.content_types:
        assert SCAN_CONTENT_TYPES[ctype] == fmt.suffix
        assert sniff_suffix(b"anything", ctype) == fmt.suffix


@pytest.mark.parametrize("fmt", [f for f in SCAN_FORMATS if f.magic], ids=lambda f: f.suffix)
def test_service_sniffs_every_format_with_magic_through_the_registry(fmt, tmp_path):
    """The service's body without a content type: the registry's sniffing decides (the
    service had its own sniffer that knew neither STL nor OBJ)."""
    from shapeverify.service.body import body_format

    path = tmp_path / f"scan{fmt.suffix}"
    WRITERS[fmt.suffix](path, np.random.default_rng(1))
    got = body_format(path.read_bytes(), None)
    assert scan_format(got).family == fmt.family


def test_cli_help_lists_the_registry_and_its_units():
    text = scan_help()
    assert all(s in text.split(" (")[0].split() for s in SCAN_SUFFIXES)
    for f in SCAN_FORMATS:
        if f.unit != "mm":
            assert f"{f.suffix} files are" in text


def test_scan_reader_imports_nothing_until_used():
    """The CLI builds its help from the registry: importing it must not import numpy."""
    import subprocess
    import sys

    code = ("import sys; import shapeverify.io.formats as f; f.scan_help(); "
            "assert 'numpy' not in sys.modules, 'numpy imported'")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
