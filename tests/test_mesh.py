"""Mesh readers (shapeverify.io.mesh): STL ascii/binary, PLY with faces, OBJ."""

from __future__ import annotations

import numpy as np
import pytest

from shapeverify.errors import CADImportError, EmptyModelError, UnsupportedFormatError
from shapeverify.io.mesh import MESH_EXTENSIONS, read_mesh
from shapeverify.io.points import write_ply

# unit cube: 8 vertices, 12 outward-wound triangles
CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                   [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
CUBE_T = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                   [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def tri_set(v, t):
    """Triangles as a set of coordinate triples (independent of vertex numbering), keeping the
    cyclic winding (rotated so that the smallest corner comes first)."""
    out = set()
    for tri in t:
        c = [tuple(v[i]) for i in tri]
        k = c.index(min(c))
        out.add(tuple(c[k:] + c[:k]))
    return out


def write_binary_stl(path, v, t):
    rec = np.zeros(len(t), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = v[t]
    path.write_bytes(b"binary stl".ljust(80, b" ") + np.uint32(len(t)).tobytes() + rec.tobytes())


def write_ascii_stl(path, v, t, name="cube"):
    lines = [f"solid {name}"]
    for tri in t:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += ["      vertex " + " ".join(repr(float(x)) for x in v[i]) for i in tri]
        lines += ["    endloop", "  endfacet"]
    lines.append(f"endsolid {name}")
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("binary", [True, False])
def test_stl_round_trip_merges_vertices(tmp_path, binary):
    p = tmp_path / "cube.stl"
    (write_binary_stl if binary else write_ascii_stl)(p, CUBE_V, CUBE_T)
    v, t = read_mesh(p)
    assert v.dtype == np.float64 and t.dtype == np.int32
    assert v.shape == (8, 3) and t.shape == (12, 3)  # soup merged back to 8 shared vertices
    assert tri_set(v, t) == tri_set(CUBE_V, CUBE_T)


def test_stl_ascii_starting_with_solid_but_binary(tmp_path):
    # binary STL whose 80-byte header starts with "solid": the size decides
    p = tmp_path / "tricky.stl"
    write_binary_stl(p, CUBE_V, CUBE_T)
    data = bytearray(p.read_bytes())
    data[:5] = b"solid"
    p.write_bytes(bytes(data))
    v, t = read_mesh(p)
    assert tri_set(v, t) == tri_set(CUBE_V, CUBE_T)


def test_ply_mesh_quads_fan_triangulated(tmp_path):
    p = tmp_path / "quad.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                 "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n4 0 1 2 3\n3 1 4 2\n")
    v, t = read_mesh(p)
    np.testing.assert_array_equal(t, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    assert v.shape == (5, 3)


def test_ply_binary_mesh(tmp_path):
    p = write_ply(tmp_path / "cube.ply", CUBE_V, faces=CUBE_T)
    v, t = read_mesh(p)
    np.testing.assert_array_equal(v, CUBE_V)
    np.testing.assert_array_equal(t, CUBE_T)


def test_obj_index_forms_and_negative_indices(tmp_path):
    p = tmp_path / "m.obj"
    p.write_text(
        "# comment\nmtllib x.mtl\no thing\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\n"
        "vt 0 0\nvt 1 0\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3//1\n"          # v/vt/vn and v//vn
        "f -4 -2 -1\n"                   # negative: 1 3 4
        "v 2 0 0\nv 2 1 0\n"
        "usemtl red\ns off\n"
        "f 2/1 5/2 6/1 3/1\n")           # quad with v/vt -> fan
    v, t = read_mesh(p)
    assert v.shape == (6, 3)
    np.testing.assert_array_equal(v[3], [0, 1, 0])
    np.testing.assert_array_equal(t, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]])


# ------------------------------------------------------------------------------ bad input
def test_unsupported_extension(tmp_path):
    p = tmp_path / "m.3ds"
    p.write_bytes(b"xx")
    with pytest.raises(UnsupportedFormatError) as e:
        read_mesh(p)
    assert "m.3ds" in str(e.value) and all(x in str(e.value) for x in MESH_EXTENSIONS)


@pytest.mark.parametrize("ext", MESH_EXTENSIONS)
def test_empty_file(tmp_path, ext):
    p = tmp_path / f"empty{ext}"
    p.write_bytes(b"")
    with pytest.raises(CADImportError, match="empty") as e:
        read_mesh(p)
    assert str(p) in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_mesh(tmp_path / "none.stl")


@pytest.mark.parametrize("content, exc, what", [
    (b"\x01\x02garbage that is neither", CADImportError, "not an STL"),
    (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n",
     CADImportError, "not a multiple of 3"),
    (b"solid x\nvertex 0 0 0\nvertex 1 0\nvertex a b c\nendsolid", CADImportError,
     "without three numbers"),
    (b"solid x\nendsolid x\n", CADImportError, "without any 'vertex'"),
])
def test_stl_bad(tmp_path, content, exc, what):
    p = tmp_path / "bad.stl"
    p.write_bytes(content)
    with pytest.raises(exc, match=what) as e:
        read_mesh(p)
    assert "bad.stl" in str(e.value)


def test_stl_binary_truncated(tmp_path):
    p = tmp_path / "trunc.stl"
    write_binary_stl(p, CUBE_V, CUBE_T)
    p.write_bytes(p.read_bytes()[:-30])
    with pytest.raises(CADImportError, match="trunc.stl"):
        read_mesh(p)


def test_stl_nan_vertex(tmp_path):
    p = tmp_path / "nan.stl"
    v = CUBE_V.copy()
    v[6] = np.nan
    write_binary_stl(p, v, CUBE_T)
    with pytest.raises(CADImportError, match="NaN"):
        read_mesh(p)


@pytest.mark.parametrize("content, exc, what", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", CADImportError, r"out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", CADImportError, r"out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", CADImportError, r"out of range"),
    ("v 0 0 0\nv 1 0\n", CADImportError, r"malformed vertex"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", CADImportError, r"fewer than 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf a b c\n", CADImportError, r"malformed face"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", EmptyModelError, r"no faces"),
    ("# nothing\n", CADImportError, r"no vertices"),
])
def test_obj_bad(tmp_path, content, exc, what):
    p = tmp_path / "bad.obj"
    p.write_text(content)
    with pytest.raises(exc, match=what) as e:
        read_mesh(p)
    assert "bad.obj" in str(e.value)


def test_ply_without_faces_is_not_a_mesh(tmp_path):
    p = write_ply(tmp_path / "cloud.ply", CUBE_V)
    with pytest.raises(EmptyModelError, match="no faces"):
        read_mesh(p)


def test_ply_corrupt_mesh(tmp_path):
    p = tmp_path / "bad.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 1\nend_header\n")
    with pytest.raises(CADImportError, match="bad.ply"):
        read_mesh(p)
