"""Mesh scans (issue 30, item 1): STL / PLY / OBJ triangles read as measured points -- area
weights of the vertices, or points sampled uniformly by area at the mesh's own resolution."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from shapeverify.errors import ScanError
from shapeverify.io.mesh_scan import median_edge, read_mesh_scan, sample_mesh, vertex_areas
from shapeverify.io.points import ply_bytes

CUBE_V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) * 10.0
CUBE_T = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def _stl(v, t) -> bytes:   # the binary STL layout of the format's definition, written here
    out = [b"\0" * 80, struct.pack("<I", len(t))]
    for tri in t:
        out.append(struct.pack("<12fH", 0, 0, 0, *v[tri].ravel(), 0))
    return b"".join(out)


def _obj(v, t) -> str:
    return ("".join(f"v {a} {b} {c}\n" for a, b, c in v)
            + "".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in t))


@pytest.fixture
def cube_files(tmp_path):
    (tmp_path / "c.stl").write_bytes(_stl(CUBE_V, CUBE_T))
    (tmp_path / "c.obj").write_text(_obj(CUBE_V, CUBE_T))
    (tmp_path / "c.ply").write_bytes(ply_bytes(CUBE_V, faces=CUBE_T))
    return [tmp_path / f"c{s}" for s in (".stl", ".obj", ".ply")]


def test_vertex_weights_are_a_third_of_the_adjacent_area_and_sum_to_the_area(cube_files):
    for p in cube_files:
        pts, w = read_mesh_scan(p, "vertices")
        assert len(pts) == 8
        np.testing.assert_allclose(w.sum(), 600.0)            # 6 faces of 10 x 10 mm
        # a cube corner touches 3 faces; how many of its 6 half-squares use it depends on
        # the diagonals: check each against the brute-force sum over triangles
        expect = {tuple(v): 0.0 for v in CUBE_V}
        for tri in CUBE_T:
            for i in tri:
                expect[tuple(CUBE_V[i])] += 50.0 / 3.0
        np.testing.assert_allclose(w, [expect[tuple(q)] for q in pts])


def test_samples_lie_on_the_cube_and_their_density_is_the_meshs_own(cube_files):
    for p in cube_files:
        pts, w = read_mesh_scan(p)
        s = median_edge(CUBE_V, CUBE_T)                        # 10 (sides; diagonals 14.1)
        assert s == 10.0
        expected = 600.0 / (np.sqrt(3) / 2 * s * s)            # 69.3 points on average
        assert abs(len(pts) - expected) < 4 * np.sqrt(expected) + 12   # stochastic rounding
        on_face = np.isclose(pts, 0.0, atol=1e-9) | np.isclose(pts, 10.0, atol=1e-9)
        assert on_face.any(axis=1).all()
        assert (pts >= -1e-9).all() and (pts <= 10 + 1e-9).all()
        np.testing.assert_allclose(w.sum(), 600.0)
    a = read_mesh_scan(cube_files[0], spacing=1.0, seed=3)[0]
    b = read_mesh_scan(cube_files[1], spacing=1.0, seed=3)[0]
    np.testing.assert_array_equal(a, b)                       # same mesh, same seed, same points


def test_sampling_is_uniform_by_area_not_by_triangle_count():
    # a 10 x 10 square: one half is 1 triangle, the other 200 slivers; vertex counting would
    # put almost all the weight on the slivered half, area sampling puts half there
    v = [[0, 0, 0], [10, 0, 0], [0, 10, 0]]
    fan = np.linspace(0, 1, 201)
    v += [[10, 10 * f, 0] for f in fan] + [[10 * (1 - f), 10, 0] for f in fan[1:]]
    v = np.array(v, float)
    t = [[0, 1, 2]] + [[2, 3 + i, 4 + i] for i in range(len(v) - 4)]
    t = np.array(t)
    np.testing.assert_allclose(vertex_areas(v, t).sum(), 100.0)
    pts = sample_mesh(v, t, spacing=0.2, seed=1)
    big = pts[:, 0] + pts[:, 1] <= 10.0
    assert abs(big.mean() - 0.5) < 0.02, big.mean()
    n = 100.0 / (np.sqrt(3) / 2 * 0.04)
    assert abs(len(pts) - n) < 4 * np.sqrt(n) + 200


def test_samples_of_a_sphere_mesh_lie_between_the_chords_and_the_sphere():
    r, n = 25.0, 24
    th, ph = np.meshgrid(np.linspace(0.2, np.pi - 0.2, n), np.linspace(0, 2 * np.pi, 2 * n,
                                                                      endpoint=False), indexing="ij")
    v = r * np.column_stack([np.sin(th).ravel() * np.cos(ph).ravel(),
                             np.sin(th).ravel() * np.sin(ph).ravel(), np.cos(th).ravel()])
    idx = np.arange(n * 2 * n).reshape(n, 2 * n)
    t = []
    for i in range(n - 1):
        for j in range(2 * n):
            a, b, c, d = idx[i, j], idx[i, (j + 1) % (2 * n)], idx[i + 1, j], idx[i + 1, (j + 1) % (2 * n)]
            t += [[a, c, b], [b, c, d]]
    t = np.array(t)
    pts = sample_mesh(v, t, seed=2)
    rad = np.linalg.norm(pts, axis=1)
    assert rad.max() <= r + 1e-9
    edge = np.linalg.norm(v[t[:, 1]] - v[t[:, 0]], axis=1).max()
    assert rad.min() >= r - edge ** 2 / (4 * r) - 1e-9        # sagitta bound of the chords


def test_damaged_or_empty_mesh_scans_are_scan_errors_naming_the_file(tmp_path):
    p = tmp_path / "m.stl"
    data = _stl(CUBE_V, CUBE_T)
    p.write_bytes(data[:300] + b"\x01" * 8 + data[300:])
    with pytest.raises(ScanError, match=r"m\.stl: the binary STL header declares 12 triangles"):
        read_mesh_scan(p)
    q = tmp_path / "pts.ply"
    q.write_bytes(ply_bytes(CUBE_V))
    with pytest.raises(ScanError, match=r"pts\.ply: PLY file has no faces"):
        read_mesh_scan(q)
    with pytest.raises(ScanError, match="unknown mesh-scan method 'all'"):
        read_mesh_scan(p, "all")
    flat = tmp_path / "flat.obj"
    flat.write_text(_obj(np.zeros((3, 3)), np.array([[0, 1, 2]])))
    with pytest.raises(ScanError, match="zero area"):
        read_mesh_scan(flat)
    with pytest.raises(ScanError, match="limit"):
        read_mesh_scan(_write(tmp_path / "big.obj"), spacing=1e-6)    # 7e14 points asked


def _write(p):
    p.write_text(_obj(CUBE_V, CUBE_T))
    return p
