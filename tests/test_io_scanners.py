"""E57 and LAS/LAZ scans (issue 30 item 1): read exactly, poses and units applied, damaged files
refused with the file's name, never a crash or a silent truncation.

E57 files are written by pye57 (libE57Format), LAS files byte by byte in the test itself from
the ASPRS LAS 1.2 specification (an independent writer: laspy is the reader)."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial.transform import Rotation

pye57 = pytest.importorskip("pye57", reason="the scanners extra (pye57) is not installed")
laspy = pytest.importorskip("laspy", reason="the scanners extra (laspy) is not installed")

from shapeverify.errors import ScanError  # noqa: E402
from shapeverify.io.e57 import read_e57_views, write_e57  # noqa: E402
from shapeverify.io.points import read_points  # noqa: E402


def _crc32c(b: bytes) -> int:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    c = 0xFFFFFFFF
    for x in b:
        c = table[(c ^ x) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def _two_scans(tmp_path):
    """Two scans in metres that float32 holds exactly, the second with a pose."""
    rng = np.random.default_rng(7)
    a = rng.normal(size=(400, 3)).astype(np.float32).astype(np.float64)
    b = rng.normal(size=(250, 3)).astype(np.float32).astype(np.float64)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.4, -0.3, 1.2]).as_matrix()
    T[:3, 3] = [1.25, -0.5, 2.0]          # metres
    path = tmp_path / "two.e57"
    f = pye57.E57(str(path), mode="w")
    for pts, pose in ((a, np.eye(4)), (b, T)):
        x, y, z, w = Rotation.from_matrix(pose[:3, :3]).as_quat()
        f.write_scan_raw({"cartesianX": pts[:, 0], "cartesianY": pts[:, 1],
                          "cartesianZ": pts[:, 2]}, rotation=np.array([w, x, y, z]),
                         translation=pose[:3, 3])
    f.close()
    return path, a, b, T


def test_e57_two_scans_read_exactly_with_their_poses_in_mm(tmp_path):
    path, a, b, T = _two_scans(tmp_path)
    views = read_e57_views(path)
    assert [len(v.points) for v in views] == [400, 250]
    np.testing.assert_allclose(views[0].points, a * 1000.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(views[1].points, (b @ T[:3, :3].T + T[:3, 3]) * 1000.0,
                               rtol=0, atol=1e-6)
    np.testing.assert_allclose(views[1].T_file_scan[:3, 3], T[:3, 3] * 1000.0, atol=1e-9)
    merged = read_points(path)
    np.testing.assert_array_equal(merged, np.concatenate([views[0].points, views[1].points]))
    assert np.array_equal(read_points(path.read_bytes(), "e57"), merged)


def test_e57_invalid_points_are_left_out(tmp_path):
    pts = np.arange(30, dtype=np.float64).reshape(10, 3) / 8
    flags = np.zeros(10, np.int8)
    flags[[2, 5]] = 1
    f = pye57.E57(str(tmp_path / "inv.e57"), mode="w")
    f.write_scan_raw({"cartesianX": pts[:, 0], "cartesianY": pts[:, 1], "cartesianZ": pts[:, 2],
                      "cartesianInvalidState": flags})
    f.close()
    got = read_points(tmp_path / "inv.e57")
    np.testing.assert_array_equal(got, pts[flags == 0] * 1000.0)


def test_e57_header_declaring_billions_of_points_is_refused_before_allocating(tmp_path):
    """A recordCount raised in the XML (page checksum recomputed) must not allocate gigabytes."""
    path, *_ = _two_scans(tmp_path)
    data = bytearray(path.read_bytes())
    old = b'recordCount="400"'
    i = data.find(old)
    new = b'recordCount="4000000000"'
    page = i // 1024
    # keep the XML's length: take the extra characters from the indentation that follows
    j = data.find(b"\n" + b" " * (len(new) - len(old)), i)
    assert j // 1024 == page and j > i
    data[j + 1:j + 1 + len(new) - len(old)] = b""
    data[i:i + len(old)] = new
    start = page * 1024
    data[start + 1020:start + 1024] = _crc32c(bytes(data[start:start + 1020])).to_bytes(4, "big")
    bad = tmp_path / "huge.e57"
    bad.write_bytes(bytes(data))
    with pytest.raises(ScanError, match=r"huge\.e57.*declares 4000000250 points"):
        read_points(bad)


def _fuzz_bytes(good: bytes, fmt: str, examples: int, accept) -> None:
    """Mutated copies of ``good`` read as ``fmt``: a ScanError naming the input, or points that
    ``accept(points)`` takes; never another exception or a crash."""
    name = f"mutant.{fmt}"

    @settings(max_examples=examples, deadline=None, derandomize=True)
    @given(st.lists(st.tuples(st.integers(0, len(good) - 1), st.integers(0, 255)),
                    min_size=1, max_size=8))
    def check(edits):
        data = bytearray(good)
        for pos, val in edits:
            data[pos] = val
        try:
            got = read_points(bytes(data), fmt, name=name)
        except ScanError as exc:
            assert name in str(exc)
        else:
            assert accept(got)

    check()


def test_e57_damaged_bytes_named_never_crash(tmp_path):
    path, *_ = _two_scans(tmp_path)
    good = path.read_bytes()
    want = read_points(good, "e57")
    # every page carries a CRC: a change the reader uses is refused, any other reads the same
    _fuzz_bytes(good, "e57", 40, lambda got: np.array_equal(got, want))


def _las12(points_m, scale=0.001, offset=(0.0, 0.0, 0.0), declared=None) -> bytes:
    """A LAS 1.2 file, point format 0, written from the ASPRS specification."""
    n = len(points_m)
    declared = n if declared is None else declared
    rec = np.round((np.asarray(points_m) - offset) / scale).astype("<i4")
    mins, maxs = np.asarray(points_m).min(0), np.asarray(points_m).max(0)
    hdr = b"LASF" + struct.pack("<HH", 0, 0) + b"\0" * 16 + bytes([1, 2])
    hdr += b"shapeverify-test".ljust(32, b"\0") + b"hand-written".ljust(32, b"\0")
    hdr += struct.pack("<HHHIIBHI", 1, 2026, 227, 227, 0, 0, 20, declared)
    hdr += struct.pack("<5I", declared, 0, 0, 0, 0)
    hdr += struct.pack("<3d", scale, scale, scale) + struct.pack("<3d", *offset)
    hdr += struct.pack("<6d", maxs[0], mins[0], maxs[1], mins[1], maxs[2], mins[2])
    assert len(hdr) == 227
    body = b"".join(struct.pack("<3iHBBbBH", *r, 0, 0, 0, 0, 0, 0) for r in rec.tolist())
    return hdr + body


def test_las_written_from_the_specification_reads_exactly():
    rng = np.random.default_rng(3)
    ints = rng.integers(-10**6, 10**6, size=(300, 3))
    offset = (1000.0, -20.0, 5.0)
    pts = ints * 0.001 + offset
    got = read_points(_las12(pts, offset=offset), "las", name="hand.las")
    np.testing.assert_allclose(got, pts, rtol=0, atol=1e-9)


def test_las_declaring_more_points_than_it_holds_is_refused():
    pts = np.arange(30, dtype=float).reshape(10, 3)
    with pytest.raises(ScanError, match=r"short\.las.*declares 20 points"):
        read_points(_las12(pts, declared=20), "las", name="short.las")


def test_las_damaged_bytes_named_never_crash():
    rng = np.random.default_rng(5)
    good = _las12(rng.integers(0, 1000, size=(40, 3)) * 0.001)
    # LAS has no checksum: a changed coordinate byte is a changed coordinate, but never more
    # points than declared, and never a crash
    _fuzz_bytes(good, "las", 60, lambda got: got.shape[1] == 3 and len(got) <= 40)


def test_service_sniffs_e57_and_las_bodies(tmp_path):
    pytest.importorskip("fastapi", reason="the service extra is not installed")
    from shapeverify.service.body import sniff_suffix

    path, *_ = _two_scans(tmp_path)
    assert sniff_suffix(path.read_bytes()) == ".e57"
    assert sniff_suffix(_las12(np.eye(3))) == ".las"
    assert sniff_suffix(b"", "application/x-e57") == ".e57"


# ------------------------------------------------------------------------------ mesh scans
def _grid_mesh(n=20, h=1.0):
    """A z = 0.01 (x^2 + y^2) patch as an even triangle mesh (n x n vertices, spacing h)."""
    x, y = np.meshgrid(np.arange(n) * h, np.arange(n) * h, indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), 0.01 * (x.ravel() ** 2 + y.ravel() ** 2)])
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel()
    return v, np.concatenate([np.column_stack([a, b, c]), np.column_stack([b, d, c])])


def _binary_stl(v, t) -> bytes:
    rec = np.zeros(len(t), np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")]))
    rec["v"] = v[t]
    return b"\0" * 80 + np.uint32(len(t)).tobytes() + rec.tobytes()


def test_mesh_scan_of_an_even_mesh_is_exactly_its_vertices():
    v, t = _grid_mesh()
    got = read_points(_binary_stl(v, t), "stl", name="even.stl")
    want = np.unique(v.astype(np.float32).astype(np.float64), axis=0)
    np.testing.assert_array_equal(np.unique(got, axis=0), want)
    assert len(got) == len(v)   # the STL soup's six copies of each vertex are one point


def test_mesh_scan_of_a_decimated_mesh_fills_large_flat_triangles_to_the_mesh_resolution():
    """Half a plate as a fine mesh, the other half as two large triangles (a scanner's
    decimation of a flat area): the points per area of both halves agree within 30 %."""
    v, t = _grid_mesh(n=21, h=0.5)            # 10 x 10 mm fine half, 0.5 mm spacing
    v[:, 2] = 0.0
    big = np.array([[10, 0, 0], [20, 0, 0], [10, 10, 0], [20, 10, 0.]])
    verts = np.vstack([v, big])
    n0 = len(v)
    tris = np.vstack([t, [[n0, n0 + 1, n0 + 2], [n0 + 1, n0 + 3, n0 + 2]]])
    obj = ("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in verts.tolist())
           + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tris.tolist())).encode()
    got = read_points(obj, "obj", name="decimated.obj")
    assert np.all(got[:, 2] == 0.0)
    fine = np.count_nonzero(got[:, 0] < 10 - 1e-9)
    coarse = np.count_nonzero(got[:, 0] > 10 + 1e-9)
    assert abs(coarse / fine - 1.0) < 0.3, (fine, coarse)


def test_mesh_scan_damaged_file_is_a_scan_error_naming_it():
    v, t = _grid_mesh(n=5)
    data = _binary_stl(v, t)[:-30]          # cut inside the last triangle
    with pytest.raises(ScanError, match=r"cut\.stl"):
        read_points(data, "stl", name="cut.stl")
    with pytest.raises(ScanError, match=r"bad\.obj.*face index out of range"):
        read_points(b"v 0 0 0\nv 1 0 0\nf 1 2 9\n", "obj", name="bad.obj")


def test_las_header_with_billions_of_vlrs_is_refused_not_read_for_minutes():
    """Found by the fuzz test above (it took 146 s to 11 min): byte 103 set to 0xFF makes the
    header declare 4,278,190,080 variable-length records in a 1 kB file, and laspy read them
    for minutes; a random mutation also let a ``struct.error`` out.  Refused in milliseconds."""
    import time

    good = bytearray(_las12(np.arange(30, dtype=float).reshape(10, 3)))
    good[103] = 0xFF
    t0 = time.process_time()
    with pytest.raises(ScanError, match=r"vlr\.las: damaged LAS header: it declares 4278190080"):
        read_points(bytes(good), "las", name="vlr.las")
    assert time.process_time() - t0 < 1.0
