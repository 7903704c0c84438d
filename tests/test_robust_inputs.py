"""Broken and hostile input files: each test pins one bug found by trying them (docs/robustness.md).

Every case must end in a clear exception (the file named, what is wrong, what to do), never in a
plausible-looking answer.  Small inputs only.
"""

from __future__ import annotations

import codecs
import logging
import re

import numpy as np
import pytest

from shapeverify import fitting
from shapeverify.cad.load import load_model
from shapeverify.characteristics.plan import PlanError, load_plan, parse_plan
from shapeverify.errors import CADImportError, ScanError
from shapeverify.io.mesh import read_mesh
from shapeverify.io.points import ply_bytes, read_points


@pytest.fixture
def pts():
    return np.random.default_rng(3).uniform(0.0, 100.0, (40, 3))


def _ascii_ply(n_declared: int, rows, extra_header: str = "", tail: str = "") -> str:
    head = (f"ply\nformat ascii 1.0\nelement vertex {n_declared}\nproperty float x\n"
            f"property float y\nproperty float z\n{extra_header}end_header\n")
    return head + "".join(" ".join(f"{v:.6f}" for v in r) + "\n" for r in rows) + tail


# ------------------------------------------------------------------------------- PLY counts
def test_ascii_ply_with_more_vertex_lines_than_declared_is_refused(tmp_path, pts):
    # was: the first 10 of 40 points read, the rest ignored without a word
    p = tmp_path / "low.ply"
    p.write_text(_ascii_ply(10, pts))
    with pytest.raises(ScanError, match=r"low\.ply: the PLY header declares 10 lines of data "
                                        r"\(vertex 10\), the file has 40.*'element' lines"):
        read_points(p)


def test_ascii_ply_vertex_count_too_small_before_a_face_element_is_refused(tmp_path, pts):
    p = tmp_path / "faces.ply"
    p.write_text(_ascii_ply(10, pts, "element face 1\nproperty list uchar int vertex_indices\n",
                            tail="3 0 1 2\n"))
    with pytest.raises(ScanError, match=r"declares 11 lines of data \(vertex 10, face 1\), the "
                                        r"file has 41"):
        read_points(p)


def test_binary_ply_with_data_beyond_declared_count_is_refused(tmp_path, pts):
    data = ply_bytes(pts).replace(b"element vertex 40", b"element vertex 30")
    p = tmp_path / "low.ply"
    p.write_bytes(data)
    with pytest.raises(ScanError, match=r"240 bytes follow the data the PLY header declares "
                                        r"\(vertex 30\)"):
        read_points(p)
    # a stray newline after the data is no second record: still read
    p.write_bytes(ply_bytes(pts) + b"\n")
    np.testing.assert_array_equal(read_points(p), pts)


def test_real_bunny_views_read_completely(shared_data):
    # the checks above must not refuse the real Stanford files (ascii, obj_info lines)
    sizes = {}
    for name in ("bun000", "bun045", "bun090"):
        sizes[name] = len(read_points(shared_data / "scans" / "bunny" / f"{name}.ply"))
    assert sizes == {"bun000": 40256, "bun045": 40097, "bun090": 30379}


# --------------------------------------------------------------------------- point tables
def test_truncated_point_table_names_the_line_without_numpys_usecols_advice(tmp_path):
    p = tmp_path / "t.xyz"
    p.write_text("1 2 3\n4 5 6\n7 8\n")
    with pytest.raises(ScanError, match=r"t\.xyz, line 3: malformed point table: 2 values where the lines before have 3"
                       ) as e:
        read_points(p)
    assert "usecols" not in str(e.value)


def test_point_table_with_a_word_names_the_line_and_the_word(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("x,y,z\n1,2,3\n4,five,6\n")
    with pytest.raises(ScanError, match=r"w\.csv, line 3: malformed point table: 'five' is not a number"):
        read_points(p)


@pytest.mark.parametrize("encoding", ["utf-16", "utf-8-sig"])
def test_point_table_with_a_byte_order_mark_is_read(tmp_path, encoding):
    # was: UTF-16 (Windows tools) refused as "could not convert string '\x004\x00'"
    p = tmp_path / "bom.xyz"
    p.write_bytes("1 2 3\n4 5 6.5\n".encode(encoding))
    np.testing.assert_array_equal(read_points(p), [[1, 2, 3], [4, 5, 6.5]])


def test_binary_garbage_named_xyz_is_called_binary(tmp_path):
    p = tmp_path / "g.xyz"
    p.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 3000, dtype=np.uint8)) + b"\0")
    with pytest.raises(ScanError, match=r"g\.xyz: is binary data, not a text point table"):
        read_points(p)


# ------------------------------------------------------------------- content vs. suffix
def test_ply_content_named_xyz_suggests_the_ply_suffix(tmp_path, pts):
    p = tmp_path / "scan.xyz"
    p.write_bytes(ply_bytes(pts))
    with pytest.raises(ScanError, match=r"scan\.xyz, line 2: malformed point table: .*the content looks like a PLY file: give "
                                        r"it the suffix \.ply$"):
        read_points(p)


def test_stl_content_named_ply_suggests_the_stl_suffix(tmp_path):
    tri = np.zeros(2, dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
    tri["v"] = np.arange(18, dtype=np.float32).reshape(2, 3, 3)
    stl = b"\0" * 80 + np.uint32(2).tobytes() + tri.tobytes()
    p = tmp_path / "part.ply"
    p.write_bytes(stl)
    with pytest.raises(ScanError, match=r"not a PLY file.*looks like an STL file: give it the "
                                        r"suffix \.stl"):
        read_points(p)
    with pytest.raises(ScanError, match=r"not a PLY file.*looks like an STL file"):
        load_model(p)


def test_ply_content_named_stl_suggests_the_ply_suffix(tmp_path, pts):
    p = tmp_path / "mesh.stl"
    p.write_bytes(ply_bytes(pts[:3], faces=[[0, 1, 2]]))
    with pytest.raises(CADImportError, match=r"mesh\.stl: not an STL file.*looks like a PLY "
                                             r"file: give it the suffix \.ply"):
        read_mesh(p)


# ----------------------------------------------------------------- absurd coordinates
def test_coordinates_of_1e30_are_refused_not_read_as_a_huge_scan(tmp_path, pts):
    # was: read, then "scale mismatch ... 475134613172635974124307480576 times larger"
    p = tmp_path / "big.xyz"
    np.savetxt(p, pts * 1e30)
    with pytest.raises(ScanError, match=r"big\.xyz: all 40 points have coordinates beyond "
                                        r"\+-1e\+12 .*damaged"):
        read_points(p)
    with pytest.raises(ScanError, match="beyond"):
        load_model(p)              # and `prepare` of such a point cloud (was: prepared)


def test_a_few_garbage_rows_are_dropped_like_nan_rows(tmp_path, pts, caplog):
    bad = pts.copy()
    bad[[3, 7], 1] = [1e30, -3e15]
    p = tmp_path / "few.xyz"
    np.savetxt(p, bad)
    with caplog.at_level(logging.WARNING, logger="shapeverify.io.points"):
        got = read_points(p)
    np.testing.assert_array_equal(got, np.delete(pts, [3, 7], axis=0))
    assert "dropped 2 of 40 rows with coordinates beyond" in caplog.text


def test_point_cloud_model_keeps_normals_aligned_when_garbage_rows_are_dropped(tmp_path, pts):
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    normals[5] = [1.0, 0.0, 0.0]
    bad = pts.copy()
    bad[2, 0] = 1e20
    p = tmp_path / "cloud.ply"
    p.write_bytes(ply_bytes(bad, normals=normals))
    m = load_model(p)
    np.testing.assert_array_equal(m.vertices, np.delete(pts, 2, axis=0))
    np.testing.assert_array_equal(m.cloud_normals, np.delete(normals, 2, axis=0))


def test_mesh_with_a_1e30_vertex_is_refused(tmp_path):
    p = tmp_path / "m.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1e30 0\nf 1 2 3\n")
    with pytest.raises(CADImportError, match=r"m\.obj: 1 mesh vertices have coordinates beyond"):
        read_mesh(p)
    q = tmp_path / "m.ply"
    q.write_bytes(ply_bytes([[0, 0, 0], [1, 0, 0], [0, 1e30, 0]], faces=[[0, 1, 2]]))
    with pytest.raises(CADImportError, match=r"m\.ply: 1 mesh vertices have coordinates beyond"):
        load_model(q)


def test_load_model_of_a_directory_says_so(tmp_path):
    d = tmp_path / "part.stl"
    d.mkdir()
    with pytest.raises(IsADirectoryError, match=r"part\.stl: is a directory, not a model file"):
        load_model(d)


# ----------------------------------------------------------------- degenerate fitting data
_SAME = np.tile([1.0, 2.0, 3.0], (30, 1))
_LINE = np.column_stack([np.linspace(0.0, 10.0, 30), 2.0 * np.linspace(0.0, 10.0, 30),
                         np.full(30, 5.0)])


@pytest.mark.parametrize("fn", ["fit_line", "fit_plane", "fit_circle", "fit_sphere",
                                "fit_cylinder", "fit_cone"])
def test_fit_to_identical_points_raises_instead_of_a_zero_radius(fn):
    # was: fit_sphere / fit_cylinder / fit_circle radius 1e-300, converged=True
    with pytest.raises(ValueError, match=rf"{fn}: all 30 points are the same point"):
        getattr(fitting, fn)(_SAME)


@pytest.mark.parametrize("fn", ["fit_plane", "fit_circle", "fit_sphere", "fit_cylinder",
                                "fit_cone"])
def test_fit_to_collinear_points_raises_instead_of_an_arbitrary_answer(fn):
    # was: fit_plane an arbitrary normal, fit_cylinder / fit_cone radius 1e-300, converged
    with pytest.raises(ValueError, match=rf"{fn}: the 30 points lie on a straight line"):
        getattr(fitting, fn)(_LINE)


def test_fit_line_to_collinear_points_still_fits_exactly():
    fit = fitting.fit_line(_LINE)
    assert fit.rms < 1e-12
    assert abs(abs(fit.direction @ np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)) - 1.0) < 1e-12


def test_nist_tls_spheres_robust_radius_in_millimetres(shared_data):
    # the real laser-scanner spheres (metres) read through read_points and fitted in mm
    for f in sorted((shared_data / "scans" / "nist_tls_spheres").glob("SPH10[1-3].xyz")):
        fit = fitting.fit_sphere(read_points(f) * 1000.0, loss="tukey")
        assert fit.converged and abs(fit.radius - 50.0) < 1.5, (f.name, fit.radius)


# ------------------------------------------------------------------------------- plans
def test_plan_file_that_is_not_utf8_is_a_plan_error(tmp_path):
    # was: internal error UnicodeDecodeError from `inspect --plan`
    p = tmp_path / "plan.yaml"
    p.write_bytes(b"units: mm\n\xff\xfe characteristics: []\n")
    with pytest.raises(PlanError, match=r"plan\.yaml, line 2: not UTF-8 text \(byte 0xff\)"):
        load_plan(p)


def test_plan_file_with_a_byte_order_mark_is_read(tmp_path):
    p = tmp_path / "plan.yaml"
    p.write_bytes(codecs.BOM_UTF8 + b"units: mm\ncharacteristics:\n"
                  b"  - {name: S, type: surface_profile, faces: all, tol: 0.2}\n")
    assert load_plan(p).characteristics[0].name == "S"


@pytest.mark.parametrize("value, key", [(".inf", "characteristics[0].tol"),
                                        (".nan", "characteristics[0].tol")])
def test_plan_with_an_infinite_or_nan_tolerance_is_refused(value, key):
    # was: tol: .inf accepted (gt=0 holds for inf), so every part would pass
    text = f"units: mm\ncharacteristics:\n  - {{name: S, type: surface_profile, faces: all, tol: {value}}}\n"
    with pytest.raises(PlanError, match=rf"line 3, key '{re.escape(key)}': Input should be a finite number"):
        parse_plan(text, "p.yaml")


def test_plan_path_that_is_a_directory_is_a_plan_error(tmp_path):
    d = tmp_path / "plan.yaml"
    d.mkdir()
    with pytest.raises(PlanError, match="is a directory"):
        load_plan(d)


def test_semicolon_table_with_decimal_commas_is_read(tmp_path):
    # was: "1,5;2,5;3,5" split at the commas, the first row taken for a header, then refused
    p = tmp_path / "eu.csv"
    p.write_text("1,5;2,5;3,5\n4,0;5,0;6,25\n")
    np.testing.assert_array_equal(read_points(p), [[1.5, 2.5, 3.5], [4.0, 5.0, 6.25]])


def test_table_with_a_delimiter_closing_every_row_is_read(tmp_path):
    # was: "'' is not a number" (Excel-style exports end rows with the delimiter)
    p = tmp_path / "trail.csv"
    p.write_text("x,y,z,\n1,2,3,\n4,5,6,\n")
    np.testing.assert_array_equal(read_points(p), [[1, 2, 3], [4, 5, 6]])
