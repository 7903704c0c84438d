"""Scan / point-cloud readers and the PLY writer (shapeverify.io.points)."""

from __future__ import annotations

import logging
import numpy as np
import pytest

from shapeverify.errors import ScanError, UnsupportedFormatError
from shapeverify.io.points import POINT_EXTENSIONS, read_ply_full, read_points, write_ply

@pytest.fixture
def pts():
    rng = np.random.default_rng(7)
    return rng.normal(scale=50.0, size=(57, 3))


# ------------------------------------------------------------------------------------ PLY
@pytest.mark.parametrize("binary", [True, False])
def test_ply_round_trip_all_properties(tmp_path, pts, binary):
    rng = np.random.default_rng(1)
    normals = rng.normal(size=pts.shape)
    colors = rng.integers(0, 256, size=(len(pts), 3)).astype(np.uint8)
    dev = rng.normal(size=len(pts))
    p = write_ply(tmp_path / "a.ply", pts, normals=normals, colors=colors,
                  scalars={"deviation": dev}, binary=binary)
    np.testing.assert_array_equal(read_points(p), pts)  # bitwise, also for ascii (%.17g)
    full = read_ply_full(p)
    assert full.format == ("binary_little_endian" if binary else "ascii")
    assert full.faces is None
    np.testing.assert_array_equal(full.vertices, pts)
    np.testing.assert_array_equal(np.column_stack([full.properties[c] for c in ("nx", "ny", "nz")]),
                                  normals)
    np.testing.assert_array_equal(
        np.column_stack([full.properties[c] for c in ("red", "green", "blue")]), colors)
    np.testing.assert_array_equal(full.properties["deviation"], dev)
    assert "PlyData(vertices=57" in repr(full)


def test_ply_float_colors_and_faces(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], float)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    for binary in (True, False):
        p = write_ply(tmp_path / f"m{binary}.ply", v, colors=np.full((4, 3), 0.5), faces=f,
                      binary=binary)
        full = read_ply_full(p)
        np.testing.assert_array_equal(full.faces, f)
        assert np.all(full.properties["red"] == 128)
        np.testing.assert_array_equal(read_points(p), v)  # faces are skipped


def _write_big_endian(path):
    """A hand-made big-endian PLY: an element before the vertices, mixed types, an extra
    property, and faces with lists of different lengths (triangle + quad)."""
    verts = np.array([[1.5, -2.25, 3], [4, 5.5, -6], [7.25, 8, 9], [-1, 0, 2]])
    header = (
        "ply\nformat binary_big_endian 1.0\ncomment hand made\n"
        "element camera 1\nproperty float view_px\nproperty list uchar int tags\n"
        "element vertex 4\nproperty float x\nproperty double y\nproperty short z\n"
        "property uchar quality\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    body = bytearray()
    body += np.array([0.5], ">f4").tobytes() + np.array([2], "u1").tobytes()
    body += np.array([10, 20], ">i4").tobytes()
    rec = np.empty(4, dtype=[("x", ">f4"), ("y", ">f8"), ("z", ">i2"), ("q", "u1")])
    rec["x"], rec["y"], rec["z"], rec["q"] = verts[:, 0], verts[:, 1], verts[:, 2], 7
    body += rec.tobytes()
    body += np.array([3], "u1").tobytes() + np.array([0, 1, 2], ">i4").tobytes()
    body += np.array([4], "u1").tobytes() + np.array([0, 1, 2, 3], ">i4").tobytes()
    path.write_bytes(header.encode() + bytes(body))
    return verts


def test_ply_big_endian_mixed_types_and_polygons(tmp_path):
    p = tmp_path / "be.ply"
    verts = _write_big_endian(p)
    np.testing.assert_array_equal(read_points(p), verts)
    full = read_ply_full(p)
    assert full.format == "binary_big_endian"
    assert np.all(full.properties["quality"] == 7)
    # the quad (0, 1, 2, 3) is fan-triangulated into (0, 1, 2), (0, 2, 3)
    np.testing.assert_array_equal(full.faces, [[0, 1, 2], [0, 1, 2], [0, 2, 3]])


def test_ply_ascii_with_leading_element_and_ragged_faces(tmp_path):
    p = tmp_path / "a.ply"
    p.write_text(
        "ply\nformat ascii 1.0\nobj_info hello\nelement material 2\nproperty list uchar float c\n"
        "element vertex 3\nproperty int x\nproperty float y\nproperty double z\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
        "2 0.1 0.2\n3 0.1 0.2 0.3\n"
        "1 2 3\n4 5 6\n7 8 9.5\n"
        "3 0 1 2\n4 0 1 2 0\n")
    np.testing.assert_array_equal(read_points(p), [[1, 2, 3], [4, 5, 6], [7, 8, 9.5]])
    np.testing.assert_array_equal(read_ply_full(p).faces, [[0, 1, 2], [0, 1, 2], [0, 2, 0]])


@pytest.mark.shared
def test_bunny_scan_reads(shared_data):
    path = shared_data / "scans" / "bunny" / "bun000.ply"
    p = read_points(path)
    assert p.shape == (40256, 3) and p.dtype == np.float64
    # first and last vertex lines of the file, read independently
    lines = path.read_text().splitlines()
    start = lines.index("end_header") + 1
    np.testing.assert_array_equal(p[0], np.array(lines[start].split(), float))
    np.testing.assert_array_equal(p[-1], np.array(lines[start + 40255].split(), float))
    ext = p.max(axis=0) - p.min(axis=0)
    assert np.all((ext > 0.03) & (ext < 0.3))  # a bunny of ~15 cm, in metres


# ------------------------------------------------------------------------------ text tables
def test_xyz_with_header_and_extra_columns(tmp_path, pts):
    p = tmp_path / "a.xyz"
    table = np.column_stack([pts, np.arange(len(pts)), np.ones(len(pts))])
    np.savetxt(p, table, fmt="%.17g", header="X Y Z intensity flag", comments="")
    np.testing.assert_array_equal(read_points(p), pts)


@pytest.mark.parametrize("sep", [",", ";", "\t", " "])
def test_csv_separators(tmp_path, pts, sep):
    p = tmp_path / "a.csv"
    np.savetxt(p, pts, fmt="%.17g", delimiter=sep, header=sep.join("xyz"), comments="")
    np.testing.assert_array_equal(read_points(p), pts)


def test_txt_without_header_with_comments(tmp_path, pts):
    p = tmp_path / "a.txt"
    np.savetxt(p, pts, fmt="%.17g", header="made by a test")  # '# made by a test'
    np.testing.assert_array_equal(read_points(p), pts)


@pytest.mark.shared
def test_nist_xyz_reads(shared_data):
    p = read_points(shared_data / "scans" / "nist_tls_spheres" / "SPH101.xyz")
    assert p.shape == (6474, 3)
    np.testing.assert_array_equal(p[0], [-5.982460, 3.579440, -1.568090])


# ------------------------------------------------------------------------------------ NPY
def test_npy_shapes(tmp_path, pts):
    np.save(tmp_path / "a.npy", pts)
    np.testing.assert_array_equal(read_points(tmp_path / "a.npy"), pts)
    np.save(tmp_path / "b.npy", np.column_stack([pts, pts]).astype(np.float32))
    np.testing.assert_array_equal(read_points(tmp_path / "b.npy"), pts.astype(np.float32))
    rec = np.zeros(len(pts), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"), ("i", "u2")])
    rec["x"], rec["y"], rec["z"] = pts.T
    np.save(tmp_path / "c.npy", rec)
    np.testing.assert_array_equal(read_points(tmp_path / "c.npy"), pts)


@pytest.mark.parametrize("arr, what", [
    (np.zeros((5, 2)), "shape"), (np.zeros(6), "shape"), (np.zeros((0, 3)), "no points"),
    (np.array(["a", "b", "c"]).reshape(1, 3), "not numeric")])
def test_npy_bad(tmp_path, arr, what):
    np.save(tmp_path / "bad.npy", arr)
    with pytest.raises(ScanError, match=what) as e:
        read_points(tmp_path / "bad.npy")
    assert "bad.npy" in str(e.value)


def test_npy_pickled_object_array_refused(tmp_path):
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ScanError, match="obj.npy"):
        read_points(tmp_path / "obj.npy")


# ------------------------------------------------------------------------------------ PCD
def _pcd_header(n, data, fields="x y z intensity", size="4 4 4 4", typ="F F F F",
                count="1 1 1 1"):
    return (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\n"
            f"SIZE {size}\nTYPE {typ}\nCOUNT {count}\nWIDTH {n}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n")


def test_pcd_ascii(tmp_path, pts):
    p = tmp_path / "a.pcd"
    table = np.column_stack([pts, np.arange(len(pts))])
    p.write_text(_pcd_header(len(pts), "ascii") +
                 "\n".join(" ".join(repr(float(x)) for x in row) for row in table) + "\n")
    np.testing.assert_array_equal(read_points(p), pts)


def test_pcd_binary_mixed_fields(tmp_path, pts):
    # intensity before x, a 3-vector field, double coordinates
    p = tmp_path / "b.pcd"
    dt = np.dtype([("i", "<u2"), ("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("n", "<f4", (3,))])
    rec = np.zeros(len(pts), dt)
    rec["x"], rec["y"], rec["z"] = pts.T
    hdr = _pcd_header(len(pts), "binary", fields="intensity x y z normal", size="2 8 8 8 4",
                      typ="U F F F F", count="1 1 1 1 3")
    p.write_bytes(hdr.encode() + rec.tobytes())
    np.testing.assert_array_equal(read_points(p), pts)


def test_pcd_binary_compressed_with_a_damaged_block_is_refused(tmp_path):
    # binary_compressed is read now (tests/test_robust_inputs_hostile.py); sizes of 0 and 20
    # stray bytes are a damaged block, named with the file
    p = tmp_path / "c.pcd"
    p.write_bytes(_pcd_header(3, "binary_compressed").encode() + b"\x00" * 20)
    with pytest.raises(ScanError, match="compressed block declares 0 bytes") as e:
        read_points(p)
    assert "c.pcd" in str(e.value)


@pytest.mark.parametrize("content, what", [
    (_pcd_header(2, "ascii", fields="x y i", size="4 4 4", typ="F F F", count="1 1 1")
     + "1 2 3\n4 5 6\n", "no field 'z'"),
    (_pcd_header(3, "ascii") + "1 2 3 4\n5 6 7 8\n", "declares 3 points"),
    (_pcd_header(2, "ascii") + "1 2 3\n4 5 6\n", "3 values"),
    (_pcd_header(2, "ascii", size="4 4 4") + "1 2 3 4\n", "different lengths"),
    ("VERSION 0.7\nFIELDS x y z\n", "no DATA"),
    (_pcd_header(2, "binary") + "abc", "truncated"),
])
def test_pcd_bad(tmp_path, content, what):
    p = tmp_path / "bad.pcd"
    p.write_text(content)
    with pytest.raises(ScanError, match=what) as e:
        read_points(p)
    assert "bad.pcd" in str(e.value)


# ------------------------------------------------------------------------- non-finite rows
@pytest.mark.parametrize("ext", [".ply", ".xyz", ".csv", ".npy", ".pcd"])
def test_nan_rows_dropped_and_counted(tmp_path, pts, caplog, ext):
    bad = pts.copy()
    bad[[3, 10, 11], 1] = np.nan
    bad[20, 0] = np.inf
    p = tmp_path / f"nan{ext}"
    if ext == ".ply":
        write_ply(p, np.zeros((len(bad), 3)))  # header, then patch the body bytes
        data = p.read_bytes()
        body = data.index(b"end_header\n") + len(b"end_header\n")
        p.write_bytes(data[:body] + bad.astype("<f8").tobytes())
    elif ext == ".npy":
        np.save(p, bad)
    elif ext == ".pcd":
        p.write_text(_pcd_header(len(bad), "ascii", fields="x y z", size="4 4 4", typ="F F F",
                                 count="1 1 1")
                     + "\n".join(" ".join(repr(float(x)) for x in row) for row in bad))
    else:
        np.savetxt(p, bad, fmt="%.17g", delimiter="," if ext == ".csv" else " ")
    with caplog.at_level(logging.WARNING, logger="shapeverify.io.points"):
        out = read_points(p)
    keep = np.ones(len(bad), bool)
    keep[[3, 10, 11, 20]] = False
    np.testing.assert_array_equal(out, pts[keep])
    msgs = [r.getMessage() for r in caplog.records]
    assert any("dropped 4 of 57" in m and p.name in m for m in msgs), msgs


def test_all_rows_nan(tmp_path):
    p = tmp_path / "allnan.xyz"
    p.write_text("nan nan nan\n1 nan 2\n")
    with pytest.raises(ScanError, match="all 2 points"):
        read_points(p)


# ------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("ext", POINT_EXTENSIONS)
def test_empty_file(tmp_path, ext):
    p = tmp_path / f"empty{ext}"
    p.write_bytes(b"")
    with pytest.raises(ScanError, match="empty") as e:
        read_points(p)
    assert str(p) in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        read_points(tmp_path / "nothere.ply")
    assert "nothere.ply" in str(e.value)


def test_unsupported_extension(tmp_path):
    p = tmp_path / "scan.rcp"          # a format shapeverify does not read (Autodesk ReCap)
    p.write_bytes(b"RCP!")
    with pytest.raises(UnsupportedFormatError) as e:
        read_points(p)
    msg = str(e.value)
    assert "scan.rcp" in msg and all(x in msg for x in POINT_EXTENSIONS)


_GOOD_HEAD = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"


@pytest.mark.parametrize("content, what", [
    ("hello\n", "not a PLY"),
    ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n1\n", "no 'end_header'"),
    ("ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown format"),
    ("ply\nelement vertex 1\nproperty float x\nend_header\n1\n", "no 'format'"),
    ("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n1\n",
     "unknown property type"),
    ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", "property before any element"),
    ("ply\nformat ascii 1.0\nelement vertex two\nend_header\n", "element NAME COUNT"),
    ("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int i\nend_header\n3 0 1 2\n",
     "no 'vertex' element"),
    (_GOOD_HEAD + "end_header\n1 2\n3 4\n", "no 'z' property"),
    (_GOOD_HEAD + "property float z\nend_header\n1 2 3\n", "truncated"),
    (_GOOD_HEAD + "property float z\nend_header\n1 2 3\n4 5\n", "malformed|values per line"),
    (_GOOD_HEAD + "property float z\nend_header\n1 2 3 4\n5 6 7 8\n", "4 values per line"),
    ("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
     "property float z\nend_header\n", "no vertices"),
])
def test_ply_bad(tmp_path, content, what):
    p = tmp_path / "bad.ply"
    p.write_text(content)
    with pytest.raises(ScanError, match=what) as e:
        read_points(p)
    assert "bad.ply" in str(e.value)


def test_ply_binary_truncated(tmp_path, pts):
    p = write_ply(tmp_path / "t.ply", pts)
    p.write_bytes(p.read_bytes()[:-5])
    with pytest.raises(ScanError, match="truncated"):
        read_points(p)


def test_ply_face_index_out_of_range(tmp_path):
    p = tmp_path / "f.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                 "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(ScanError, match="out of range"):
        read_ply_full(p)


@pytest.mark.parametrize("content, what", [
    ("1 2\n3 4\n", "2 column"),
    ("1 2 3\n4 5\n", "malformed"),
    ("x y z\n1 2 3\nfoo bar baz\n", "malformed"),
    ("# only a comment\n\n", "no points"),
    ("x y z\n", "header line but no points"),
])
def test_table_bad(tmp_path, content, what):
    p = tmp_path / "bad.xyz"
    p.write_text(content)
    with pytest.raises(ScanError, match=what) as e:
        read_points(p)
    assert "bad.xyz" in str(e.value)


# ------------------------------------------------------------------------------ write_ply
@pytest.mark.parametrize("kwargs, what", [
    ({"points": np.zeros((3, 2))}, "points must have shape"),
    ({"points": np.array([[0, 0, np.nan]])}, "NaN"),
    ({"normals": np.zeros((2, 3))}, "normals"),
    ({"colors": np.full((3, 3), 2.0)}, r"\[0, 1\]"),
    ({"colors": np.full((3, 3), 300)}, "0..255"),
    ({"colors": np.zeros((3, 2), np.uint8)}, "colors must have shape"),
    ({"scalars": {"bad name": np.zeros(3)}}, "identifier"),
    ({"scalars": {"x": np.zeros(3)}}, "clashes"),
    ({"scalars": {"d": np.zeros(4)}}, "shape"),
    ({"faces": np.array([[0, 1, 5]])}, "face indices"),
    ({"faces": np.array([[0.0, 1, 2]])}, "integer"),
])
def test_write_ply_validation(tmp_path, kwargs, what):
    args = {"points": np.zeros((3, 3))} | kwargs
    with pytest.raises(ValueError, match=what):
        write_ply(tmp_path / "w.ply", **args)


# ------------------------------------------------- sources: a path, bytes, a binary file object
def _scan_file_bytes(ext: str, pts: np.ndarray) -> bytes:
    """An ``.xyz`` scan with a header, a comment and a NaN row.  (Every registered format is
    read from a path, bytes and a file object in ``tests/test_scan_formats.py``, the one
    round-trip suite over the registry.)"""
    assert ext == ".xyz"
    with_nan = np.vstack([pts, [np.nan, 1.0, 2.0]])
    return ("x y z\n# a comment\n" + "\n".join(" ".join(repr(float(v)) for v in r)
                                          for r in with_nan)).encode()


@pytest.mark.parametrize("ext", POINT_EXTENSIONS)
def test_a_bad_scan_gives_the_same_error_from_bytes_naming_the_given_name(tmp_path, ext):
    bad = {".ply": b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n",
           ".npy": b"\x93NUMPY\x01\x00garbage", ".pcd": b"VERSION .7\nFIELDS x y\n"}.get(ext, b"x y z\n1 2\n")
    path = tmp_path / f"bad{ext}"
    path.write_bytes(bad)
    with pytest.raises(ScanError) as from_path:
        read_points(path)
    with pytest.raises(ScanError) as from_bytes:
        read_points(bad, ext, name="upload #3")
    assert str(from_bytes.value) == str(from_path.value).replace(str(path), "upload #3")
    assert str(from_bytes.value).startswith("upload #3: ")


def test_bytes_need_a_format_and_text_mode_files_are_refused(tmp_path, pts):
    import io

    data = _scan_file_bytes(".xyz", pts)
    with pytest.raises(ValueError, match="give the format"):
        read_points(data)
    with pytest.raises(UnsupportedFormatError, match=r"'\.rcp'.*\.ply, \.xyz"):
        read_points(data, ".rcp")
    with pytest.raises(ScanError, match="empty"):
        read_points(b"", ".ply")
    with pytest.raises(TypeError, match="binary mode"):
        read_points(io.StringIO(data.decode()), ".xyz")
    with pytest.raises(TypeError, match="path, bytes or a binary file object"):
        read_points(12345, ".xyz")


def test_one_suffix_list_serves_the_readers_and_batch():
    import shapeverify.batch as batch
    from shapeverify.io.formats import SCAN_READERS, SCAN_SUFFIXES

    assert POINT_EXTENSIONS is SCAN_SUFFIXES and batch.SCAN_SUFFIXES is SCAN_SUFFIXES
    assert tuple(SCAN_READERS) == SCAN_SUFFIXES


@pytest.mark.parametrize("binary", [True, False])
def test_ply_bytes_are_what_write_ply_writes_and_read_ply_full_reads_them(tmp_path, pts, binary):
    from shapeverify.io.points import ply_bytes

    data = ply_bytes(pts, faces=[[0, 1, 2]], binary=binary)
    path = write_ply(tmp_path / "a.ply", pts, faces=[[0, 1, 2]], binary=binary)
    assert path.read_bytes() == data
    full = read_ply_full(data)
    np.testing.assert_array_equal(full.vertices, read_ply_full(path).vertices)
    np.testing.assert_array_equal(full.faces, [[0, 1, 2]])
