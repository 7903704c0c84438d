"""Saving / loading models (shapeverify.cad.persist) and load_model's dispatch (cad/load.py)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from shapeverify.cad.load import MODEL_EXTENSIONS, load_model
from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface, sphere
from shapeverify.cad.persist import (load_saved_model, model_from_arrays, model_to_arrays,
                                     save_model)
from shapeverify.errors import (CADImportError, EmptyModelError, ScanError,
                                UnsupportedFormatError)
from shapeverify.io.points import write_ply

def built_model():
    """Three faces: a rational sphere, a non-rational wavy patch with two holes and mixed free
    flags (reversed), and a bilinear plane."""
    rng = np.random.default_rng(11)
    f0 = Face(sphere(7.5, center=(1, 2, 3)), (np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]),),
              (np.zeros(4, bool),), False)
    n = 6
    X, Y = np.meshgrid(np.linspace(0, 9, n), np.linspace(0, 7, n), indexing="ij")
    ctrl = np.stack([X, Y, rng.normal(size=(n, n))], axis=-1)
    knots = [0, 0, 0, 0, 0.1, 0.7, 1, 1, 1, 1]
    patch = NurbsSurface(3, 3, knots, knots, ctrl)
    t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    holes = [np.column_stack([0.3 + 0.1 * np.cos(t), 0.4 - 0.1 * np.sin(t)]),
             np.column_stack([0.7 + 0.05 * np.cos(t), 0.6 - 0.05 * np.sin(t)])]
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    free = (np.array([True, False, True, False]), rng.random(50) < 0.5, np.ones(50, bool))
    f1 = Face(patch, (outer, *holes), free, True)
    pl = NurbsSurface(1, 1, [0, 0, 2, 2], [-1, -1, 1, 1],
                      np.array([[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0.0]]]))
    f2 = Face(pl, (np.array([[0, -1], [2, -1], [2, 1.0]]),), (np.ones(3, bool),), False)
    return Model(faces=(f0, f1, f2), unit="inch", scale_to_mm=25.4, source="built in a test",
                 kind="cad")


def assert_same_model(a, b):
    assert (a.kind, a.unit, a.scale_to_mm, a.source) == (b.kind, b.unit, b.scale_to_mm, b.source)
    assert len(a.faces) == len(b.faces)
    for fa, fb in zip(a.faces, b.faces):
        sa, sb = fa.surface, fb.surface
        assert (sa.degree_u, sa.degree_v) == (sb.degree_u, sb.degree_v)
        for name in ("knots_u", "knots_v", "control"):
            x, y = getattr(sa, name), getattr(sb, name)
            assert x.dtype == y.dtype and x.shape == y.shape
            assert x.tobytes() == y.tobytes()  # bitwise
        assert (sa.weights is None) == (sb.weights is None)
        if sa.weights is not None:
            assert sa.weights.tobytes() == sb.weights.tobytes()
        assert fa.reversed == fb.reversed
        assert len(fa.loops) == len(fb.loops)
        for la, lb, ra, rb in zip(fa.loops, fb.loops, fa.loop_free, fb.loop_free):
            assert la.tobytes() == lb.tobytes() and la.shape == lb.shape
            np.testing.assert_array_equal(ra, rb)
    for name in ("vertices", "triangles", "cloud_normals"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None)
        if x is not None:
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def test_cad_round_trip_bitwise(tmp_path):
    m = built_model()
    p = save_model(m, tmp_path / "part.svmodel")
    assert p == tmp_path / "part.svmodel" and not (tmp_path / "part.svmodel.tmp").exists()
    m2 = load_saved_model(p)
    assert_same_model(m, m2)
    # the loaded model samples to exactly the same points
    a, b = m.sample(0.5), m2.sample(0.5)
    assert a.points.tobytes() == b.points.tobytes()
    np.testing.assert_array_equal(a.boundary, b.boundary)
    # plain npz without objects: loads with allow_pickle=False, no object dtype
    with np.load(p, allow_pickle=False) as z:
        assert all(z[k].dtype != object for k in z.files)


def test_model_save_method_and_load_model(tmp_path):
    m = built_model()
    m.save(tmp_path / "x.svmodel")
    assert_same_model(m, load_model(tmp_path / "x.svmodel"))
    assert_same_model(m, model_from_arrays(model_to_arrays(m)))


def test_mesh_and_cloud_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    mesh = Model(kind="mesh", source="m", vertices=rng.normal(size=(10, 3)),
                 triangles=rng.integers(0, 10, size=(7, 3)))
    cloud = Model(kind="points", source="c", vertices=rng.normal(size=(20, 3)),
                  cloud_normals=rng.normal(size=(20, 3)))
    for m in (mesh, cloud):
        save_model(m, tmp_path / "m.svmodel")
        assert_same_model(m, load_saved_model(tmp_path / "m.svmodel"))


# ------------------------------------------------------------------------------ bad files
def test_saved_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_saved_model(tmp_path / "none.svmodel")
    (tmp_path / "empty.svmodel").write_bytes(b"")
    with pytest.raises(CADImportError, match="empty"):
        load_saved_model(tmp_path / "empty.svmodel")
    (tmp_path / "junk.svmodel").write_bytes(b"PK\x03\x04 this is not a zip")
    with pytest.raises(CADImportError, match="junk.svmodel"):
        load_model(tmp_path / "junk.svmodel")
    np.savez(tmp_path / "foreign.npz", a=np.zeros(3))
    with pytest.raises(CADImportError, match="not a shapeverify model"):
        load_saved_model(tmp_path / "foreign.npz")
    # truncated archive
    data = save_model(built_model(), tmp_path / "t.svmodel").read_bytes()
    (tmp_path / "t.svmodel").write_bytes(data[: len(data) // 2])
    with pytest.raises(CADImportError, match="t.svmodel"):
        load_saved_model(tmp_path / "t.svmodel")


def test_saved_wrong_version_and_inconsistent(tmp_path):
    a = model_to_arrays(built_model())
    meta = bytes(a["meta"]).replace(b'"version": 1', b'"version": 99')
    b = dict(a, meta=np.frombuffer(meta, np.uint8))
    with pytest.raises(CADImportError, match="version 99"):
        model_from_arrays(b, "v.svmodel")
    c = dict(a, control=a["control"][:-1])
    with pytest.raises(CADImportError, match="inconsistent"):
        model_from_arrays(c, "c.svmodel")
    d = {k: v for k, v in a.items() if k != "loops"}
    with pytest.raises(CADImportError, match="missing array"):
        model_from_arrays(d, "d.svmodel")


def test_saved_cad_without_faces(tmp_path):
    save_model(Model(faces=(), kind="cad", source="nothing"), tmp_path / "e.svmodel")
    with pytest.raises(EmptyModelError, match="no faces"):
        load_model(tmp_path / "e.svmodel")


# ----------------------------------------------------------------------- load_model dispatch
def test_load_model_mesh_and_cloud_formats(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    m = load_model(write_ply(tmp_path / "mesh.ply", v, faces=t))
    assert m.kind == "mesh" and m.unit == "mm" and m.scale_to_mm == 1.0
    np.testing.assert_array_equal(m.triangles, t)
    assert m.triangles.dtype == np.int32 and m.source.endswith("mesh.ply")
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert load_model(tmp_path / "m.obj").kind == "mesh"
    nrm = np.array([[0, 0, 2.0], [0, 3, 0], [1, 0, 0], [0, 0, 1]])
    c = load_model(write_ply(tmp_path / "cloud.ply", v, normals=nrm))
    assert c.kind == "points" and c.triangles is None
    np.testing.assert_array_equal(c.vertices, v)
    np.testing.assert_allclose(c.cloud_normals, nrm / np.linalg.norm(nrm, axis=1)[:, None])
    np.savetxt(tmp_path / "c.xyz", v)
    x = load_model(tmp_path / "c.xyz")
    assert x.kind == "points" and x.cloud_normals is None
    np.testing.assert_array_equal(x.vertices, v)


def test_load_model_cloud_ply_nan_rows_keep_normals_aligned(tmp_path):
    v = np.arange(15, dtype=float).reshape(5, 3)
    n = np.tile([0, 0, 1.0], (5, 1))
    n[3] = [1, 0, 0]
    p = write_ply(tmp_path / "c.ply", v, normals=n)
    data = bytearray(p.read_bytes())
    body = data.index(b"end_header\n") + len(b"end_header\n")
    data[body + 2 * 48: body + 2 * 48 + 8] = np.array([np.nan]).tobytes()  # x of row 2
    p.write_bytes(bytes(data))
    m = load_model(p)
    np.testing.assert_array_equal(m.vertices, v[[0, 1, 3, 4]])
    np.testing.assert_array_equal(m.cloud_normals, n[[0, 1, 3, 4]])


def test_load_model_bad_input(tmp_path):
    with pytest.raises(UnsupportedFormatError) as e:
        load_model(tmp_path / "part.dwg")
    assert "part.dwg" in str(e.value) and all(x in str(e.value) for x in MODEL_EXTENSIONS)
    with pytest.raises(FileNotFoundError):
        load_model(tmp_path / "missing.step")
    (tmp_path / "junk.step").write_text("this is not a STEP file\n")
    with pytest.raises(CADImportError, match="junk.step"):
        load_model(tmp_path / "junk.step")
    (tmp_path / "empty.igs").write_bytes(b"")
    with pytest.raises(CADImportError, match="empty"):
        load_model(tmp_path / "empty.igs")
    (tmp_path / "empty.stl").write_bytes(b"")
    with pytest.raises(CADImportError, match="empty"):
        load_model(tmp_path / "empty.stl")
    (tmp_path / "empty.xyz").write_bytes(b"")
    with pytest.raises(ScanError, match="empty"):
        load_model(tmp_path / "empty.xyz")
    p = write_ply(tmp_path / "nanmesh.ply", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]),
                  faces=[[0, 1, 2]])
    data = bytearray(p.read_bytes())
    body = data.index(b"end_header\n") + len(b"end_header\n")
    data[body: body + 8] = np.array([np.inf]).tobytes()
    p.write_bytes(bytes(data))
    with pytest.raises(CADImportError, match="NaN or infinite"):
        load_model(p)


@pytest.mark.parametrize("ext", [".step", ".igs"])
def test_load_model_cad_without_faces(tmp_path, ext):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.gp import gp_Pnt

    edge = BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(10, 0, 0)).Edge()
    path = tmp_path / f"edge{ext}"
    if ext == ".step":
        from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

        w = STEPControl_Writer()
        w.Transfer(edge, STEPControl_AsIs)
        w.Write(str(path))
    else:
        from OCP.IGESControl import IGESControl_Writer

        w = IGESControl_Writer()
        w.AddShape(edge)
        w.ComputeModel()
        w.Write(str(path))
    with pytest.raises(EmptyModelError, match="no faces") as e:
        load_model(path)
    assert path.name in str(e.value)


# ---------------------------------------------------------------------------- real model
@pytest.mark.slow
@pytest.mark.shared
def test_impeller_round_trip(tmp_path, capsys, shared_data):
    path = shared_data / "cad" / "impeller.igs"
    t0 = time.perf_counter()
    m = load_model(path)
    t_import = time.perf_counter() - t0
    assert len(m.faces) == 277
    save_model(m, tmp_path / "impeller.svmodel")
    t0 = time.perf_counter()
    m2 = load_model(tmp_path / "impeller.svmodel")
    t_load = time.perf_counter() - t0
    assert_same_model(m, m2)
    with capsys.disabled():
        print(f"\nimpeller.igs: import {t_import:.2f} s, saved-model load {t_load:.3f} s, "
              f"file {(tmp_path / 'impeller.svmodel').stat().st_size / 1e6:.2f} MB")


# ------------------------------------------- damaged .svmodel / .svm: ModelFileError, nothing else
def _damaged_copies(data: bytes, rng, n_flips: int = 30, n_cuts: int = 10):
    """(label, bytes): single bit flips at random places, and truncations at random lengths."""
    for pos in rng.integers(0, len(data), size=n_flips):
        b = bytearray(data)
        b[pos] ^= 1 << int(rng.integers(8))
        yield f"bit flip at {pos}", bytes(b)
    for cut in rng.integers(1, len(data) - 1, size=n_cuts):
        yield f"truncated to {cut}", data[:cut]


def test_damaged_svmodel_is_a_model_file_error_naming_the_file(tmp_path):
    from shapeverify.errors import ModelFileError, ShapeVerifyError

    m = built_model()
    m = Model(faces=m.faces, unit=m.unit, scale_to_mm=m.scale_to_mm, source=m.source,
              n_faces_in_file=4, skipped_faces=("face 3: no usable trimming loop",))
    data = save_model(m, tmp_path / "good.svmodel").read_bytes()
    back = load_saved_model(tmp_path / "good.svmodel")  # the face count round-trips
    assert back.n_faces_in_file == 4 and back.skipped_faces == m.skipped_faces
    rng = np.random.default_rng(5)
    outcomes = {"error": 0, "same": 0}
    for label, bad in _damaged_copies(data, rng):
        p = tmp_path / "damaged.svmodel"
        p.write_bytes(bad)
        try:
            got = load_model(p)
        except ModelFileError as exc:
            assert isinstance(exc, (ShapeVerifyError, ValueError))
            assert "damaged.svmodel" in str(exc) and "shapeverify prepare" in str(exc), label
            outcomes["error"] += 1
            continue
        assert_same_model(got, back)  # a flip in an unused header byte: the CRCs still hold
        outcomes["same"] += 1
    assert outcomes["error"] >= 30, outcomes
    # a well-formed archive with arrays of the wrong shape
    a = model_to_arrays(built_model())
    with open(tmp_path / "shapes.svmodel", "wb") as fh:
        np.savez(fh, **dict(a, shapes=a["shapes"].ravel()))
    with pytest.raises(ModelFileError, match=r"shapes\.svmodel.*shapeverify prepare"):
        load_model(tmp_path / "shapes.svmodel")


def test_damaged_svm_is_a_model_file_error_naming_the_file(tmp_path):
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.errors import ModelFileError
    from shapeverify.nearest import load_prepared, prepare

    prepare(wavy_panel(), spacing=3.0).save(tmp_path / "good.svm")
    data = (tmp_path / "good.svm").read_bytes()
    good = load_prepared(tmp_path / "good.svm")
    rng = np.random.default_rng(6)
    n_errors = 0
    for label, bad in _damaged_copies(data, rng):
        p = tmp_path / "damaged.svm"
        p.write_bytes(bad)
        try:
            got = load_prepared(p)
        except ModelFileError as exc:
            assert "damaged.svm" in str(exc) and "shapeverify prepare" in str(exc), label
            n_errors += 1
            continue
        assert got.n_points == good.n_points, label
        np.testing.assert_array_equal(got.points.points, good.points.points)
    assert n_errors >= 30
    (tmp_path / "empty.svm").write_bytes(b"")
    with pytest.raises(ModelFileError, match=r"empty\.svm.*empty.*shapeverify prepare"):
        load_prepared(tmp_path / "empty.svm")


def test_fixture_pose_is_saved_with_the_prepared_model_and_starts_inspections(tmp_path):
    import shapeverify as sv
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.nearest import load_prepared
    from shapeverify.simulate import virtual_scan
    from shapeverify.simulate.scanner import random_motion

    prep = sv.prepare(wavy_panel(), spacing=2.0)
    vs = virtual_scan(prep, pixel=2.0, noise=0.01, motion=(20.0, 300.0), rng=1)   # far away
    prep.fixture = vs.T_model_scan @ random_motion(0.5, 0.5, rng=2)              # a rough fixture
    prep.save(tmp_path / "p.svm")
    back = load_prepared(tmp_path / "p.svm")
    np.testing.assert_array_equal(back.fixture, prep.fixture)
    res = sv.inspect(back, vs.scan, tolerance=0.2)
    assert res.registration.init == "given" and res.verdict == "pass", res.reasons


def test_load_prepared_reads_bytes_and_file_objects_like_a_path(tmp_path):
    """Pins: load_prepared took only a path, so batch wrote the model's bytes to a temporary
    file in every worker. Bytes and binary file objects now give the same model; damaged
    bytes give the same ModelFileError as a damaged file."""
    import io

    from shapeverify.cad.examples import wavy_panel
    from shapeverify.errors import ModelFileError
    from shapeverify.nearest import load_prepared, prepare

    prep = prepare(wavy_panel(), spacing=2.0)
    path = tmp_path / "m.svm"
    prep.save(path)
    data = path.read_bytes()
    q = np.random.default_rng(0).uniform(-5, 5, (200, 3)) + prep.points.points[:200]
    want = load_prepared(path).closest(q)
    with open(path, "rb") as fh:
        for src in (data, bytearray(data), io.BytesIO(data), fh):
            got = load_prepared(src).closest(q)
            np.testing.assert_array_equal(got.points, want.points)
            np.testing.assert_array_equal(got.index, want.index)
    with pytest.raises(ModelFileError, match="damaged or truncated|not a prepared-model"):
        load_prepared(data[: len(data) // 2])
    with pytest.raises(ModelFileError, match="empty"):
        load_prepared(b"")
    with open(path, "r", encoding="latin-1") as text:
        with pytest.raises(TypeError, match="binary mode"):
            load_prepared(text)


def test_row5_svmodel_checksum_catches_a_consistent_change(tmp_path):
    """Issue 33 row 5 for .svmodel: a change the structure checks cannot see (a control
    point moved, the archive rewritten with a valid CRC) is caught by the header's SHA-256; a
    file without a checksum (written before it existed) still loads."""
    import json

    from shapeverify.errors import ModelFileError

    path = save_model(built_model(), tmp_path / "m.svmodel")
    with np.load(path) as z:
        a = {k: z[k] for k in z.files}
    meta = json.loads(bytes(a["meta"]).decode())
    assert len(meta["sha256"]) == 64
    a["control"] = a["control"].copy()
    a["control"][0, 0] += 1.0
    with open(tmp_path / "moved.svmodel", "wb") as fh:
        np.savez(fh, **a)
    with pytest.raises(ModelFileError, match="moved.svmodel.*checksum"):
        load_saved_model(tmp_path / "moved.svmodel")
    meta.pop("sha256")
    a["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    with open(tmp_path / "old.svmodel", "wb") as fh:
        np.savez(fh, **a)
    old = load_saved_model(tmp_path / "old.svmodel")
    assert old.faces[0].surface.control.reshape(-1, 3)[0, 0] == a["control"][0, 0]
