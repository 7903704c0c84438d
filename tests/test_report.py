"""Reports: self-contained HTML, PNG summary, coloured PLY.

The inspection result comes from ``inspect_registered`` on an analytic stand-in of a prepared
model (a 100 x 60 mm rectangle in z = 0 with exact closest points) whose CAD surface is a real
two-face :class:`shapeverify.cad.model.Model`, so the report is drawn from real data structures.
"""

from __future__ import annotations

import base64
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.inspection import inspect_registered
from shapeverify.io.points import read_ply_full
from shapeverify.report import deviation_colors, write_colored_ply, write_html_report, write_png_summary
from shapeverify.report.html import _subsample, cad_mesh


def plane_model(L=100.0, W=60.0) -> Model:
    faces = []
    for x0, x1 in ((0.0, L / 2), (L / 2, L)):
        ctrl = np.array([[[x0, 0, 0], [x0, W, 0]], [[x1, 0, 0], [x1, W, 0]]], float)
        loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        free = np.array([True, x1 == L, True, x0 == 0])
        faces.append(Face(NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl), (loop,), (free,)))
    return Model(tuple(faces), source="stand-in plane 100 x 60 mm")


class PlanePrep:
    """Stand-in Prepared model of ``plane_model()`` with exact closest points."""

    def __init__(self):
        self.model = plane_model()
        x, y = np.meshgrid(np.arange(0.5, 100.0, 1.0), np.arange(0.5, 60.0, 1.0))   # 1 mm
        pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
        self.points = SimpleNamespace(points=pts, face=(pts[:, 0] > 50).astype(np.int32), spacing=1.0)
        self.spacing = 1.0
        self.n_points = len(pts)

    def closest(self, q, exact=False):
        foot = q.copy()
        foot[:, 0] = np.clip(q[:, 0], 0, 100.0)
        foot[:, 1] = np.clip(q[:, 1], 0, 60.0)
        foot[:, 2] = 0.0
        d = np.linalg.norm(q - foot, axis=1) * np.where(q[:, 2] >= 0, 1.0, -1.0)
        return SimpleNamespace(points=foot, normals=np.tile([0.0, 0.0, 1.0], (len(q), 1)),
                               distances=d, face=(foot[:, 0] > 50).astype(np.int32), uv=foot[:, :2],
                               index=np.zeros(len(q), np.int64),
                               on_boundary=(foot[:, 0] != q[:, 0]) | (foot[:, 1] != q[:, 1]))


@pytest.fixture(scope="module")
def inspected():
    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(1, 99, 0.6), np.arange(1, 59, 0.6))
    x, y = x.ravel(), y.ravel()
    z = -0.4 * np.exp(-((x - 30) ** 2 + (y - 20) ** 2) / 18.0) + rng.normal(0, 0.02, x.size)
    scan = np.column_stack([x, y, z])
    scan = np.vstack([scan, [[50.0, 30.0, 4.0], [100.5, 30.0, 0.0]]])   # too far, off the edge
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=0.021, iterations=8, converged=True,
                          inlier_fraction=0.97, weights=np.ones(len(scan)), message="converged")
    prep = PlanePrep()
    res = inspect_registered(prep, scan, reg, tolerance=0.2)
    assert res.verdict == "fail" and len(res.regions) == 1
    return prep, scan, res


def _plotly_arrays(page: str) -> list:
    """Decode every base64 typed array ('bdata') plotly embedded in the page."""
    out = []
    for dtype, data in re.findall(r'"dtype":"(\w+)","bdata":"([^"]+)"', page):
        data = data.replace("\\u002f", "/")       # plotly escapes '/' in embedded JSON
        out.append(np.frombuffer(base64.b64decode(data), dtype=np.dtype(dtype)))
    return out


# ----------------------------------------------------------------------------- HTML
def test_html_is_one_offline_file_with_view_histogram_tables_and_units(inspected, tmp_path):
    prep, scan, res = inspected
    path = write_html_report(res, prep, scan, tmp_path / "report.html")
    page = path.read_text(encoding="utf-8")
    # self-contained: plotly.js inline (gzip + base64, unpacked by the browser: the page is a
    # third of its old size), nothing loaded from elsewhere
    import gzip

    from plotly.offline import get_plotlyjs

    packed = re.search(r'<script id="sv-plotly-gz" type="application/octet-stream">([^<]+)</script>',
                       page).group(1)
    assert gzip.decompress(base64.b64decode(packed)).decode("utf-8") == get_plotlyjs()
    assert "Plotly.newPlot" in page and "DecompressionStream" in page and len(page) < 3_000_000
    assert not re.search(r"<script[^>]*\ssrc=", page)
    assert not re.search(r"<link[^>]*\shref=", page)
    assert 'id="view3d"' in page and 'id="histogram"' in page
    assert ">FAIL<" in page and "mm" in page and "[mm]" in page
    assert "R1" in page and "Regions (most severe first)" in page and "Per-face statistics" in page
    assert "decided by rule" in page and "coverage" in page
    assert "stand-in plane 100 x 60 mm" in page
    # colour scale: diverging, centred at 0, clipped at 2 x tolerance, limits marked
    assert '"cmin":-0.4' in page and '"cmax":0.4' in page and '"cmid":0.0' in page
    assert "+0.2 upper" in page and "-0.2 lower" in page
    # the evaluated deviations are in the page (float32), the CAD surface as a mesh
    ev = res.deviations.values[res.deviations.evaluated].astype(np.float32)
    arrays = _plotly_arrays(page)
    assert any(a.dtype == np.float32 and a.size == ev.size and np.array_equal(a, ev)
               for a in arrays)
    assert '"type":"mesh3d"' in page
    assert "shows all" in page


def test_html_subsamples_large_scans_but_keeps_every_out_of_tolerance_point(inspected, tmp_path):
    prep, scan, res = inspected
    idx, sub = _subsample(res, 2000, np.random.default_rng(0))
    dev = res.deviations
    out = np.flatnonzero(dev.evaluated & ~res.tolerance.within(dev.values, dev.face))
    assert sub and idx.size == 2000 and np.isin(out, idx).all()
    assert dev.evaluated[idx].all() and np.unique(idx).size == idx.size
    page = write_html_report(res, prep, scan, tmp_path / "r.html", max_points=2000).read_text()
    assert f"shows 2,000 of {dev.n_evaluated:,} evaluated points" in page


def test_html_rejects_a_different_scan(inspected, tmp_path):
    prep, scan, res = inspected
    with pytest.raises(ValueError, match="points but the inspection has"):
        write_html_report(res, prep, scan[:-5], tmp_path / "r.html")


def test_cad_mesh_covers_the_faces():
    v, t = cad_mesh(plane_model())
    assert t.shape[1] == 3 and len(t) > 50
    tri = v[t]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    assert area == pytest.approx(100.0 * 60.0, rel=1e-6)
    assert cad_mesh(None) is None


# ----------------------------------------------------------------------------- PNG
def test_png_summary_is_a_non_blank_image(inspected, tmp_path):
    from matplotlib.image import imread

    prep, scan, res = inspected
    path = write_png_summary(res, scan, tmp_path / "summary.png")
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 600 and img.shape[1] > 1000
    assert img[..., :3].std() > 0.05
    # the verdict banner across the top is the verdict colour (#b3261e for fail)
    band = img[: int(0.1 * img.shape[0]), :, :3].reshape(-1, 3)
    red = np.all(np.abs(band - np.array([0xB3, 0x26, 0x1E]) / 255) < 0.02, axis=1)
    assert red.mean() > 0.5


# ----------------------------------------------------------------------------- PLY
def test_colored_ply_has_rgb_and_the_deviation_scalar(inspected, tmp_path):
    from matplotlib import colormaps

    prep, scan, res = inspected
    path = write_colored_ply(res, scan, tmp_path / "dev.ply")
    ply = read_ply_full(path)
    dev = res.deviations
    np.testing.assert_allclose(ply.vertices, dev.points_model)
    d = ply.properties["deviation"]
    np.testing.assert_array_equal(np.isnan(d), ~dev.evaluated)
    np.testing.assert_array_equal(d[dev.evaluated], dev.values[dev.evaluated])
    rgb = np.column_stack([ply.properties[c] for c in ("red", "green", "blue")]).astype(int)
    deepest = int(np.nanargmin(dev.values))
    assert rgb[deepest, 2] > rgb[deepest, 0] + 50 and rgb[deepest, 2] > rgb[deepest, 1]  # blue
    assert (rgb[~dev.evaluated] == 153).all()                          # not evaluated: grey
    expect = np.rint(np.array(colormaps["RdBu_r"](0.5 + 0.5 * dev.values[0] / 0.4)[:3]) * 255)
    np.testing.assert_array_equal(rgb[0], expect)


def test_deviation_colors_scale_ends_and_nan():
    from matplotlib import colormaps

    c = deviation_colors(np.array([-1.0, -0.4, 0.0, 0.4, 9.0, np.nan]), 0.4)
    cmap = colormaps["RdBu_r"]
    np.testing.assert_allclose(c[0], cmap(0.0)[:3])
    np.testing.assert_allclose(c[1], cmap(0.0)[:3])
    np.testing.assert_allclose(c[2], cmap(0.5)[:3])
    np.testing.assert_allclose(c[3], cmap(1.0)[:3])
    np.testing.assert_allclose(c[4], cmap(1.0)[:3])
    np.testing.assert_allclose(c[5], [0.6, 0.6, 0.6])


def test_result_json_matches_report_numbers(inspected):
    _, _, res = inspected
    d = json.loads(json.dumps(res.to_dict()))
    assert d["excluded"] == {"too_far": 1, "material": 0, "on_boundary": 1, "outside_faces": 0,
                             "outliers": res.outliers.n}
    assert d["deviation"]["n"] == res.deviations.n_evaluated - res.outliers.n


# ------------------------------------------------------------------ bytes or a path
@pytest.mark.slow
def test_every_writer_returns_the_bytes_its_write_function_writes(inspected, tmp_path):
    import re as _re

    from shapeverify.report import (colored_ply, html_report, png_summary, result_json,
                                    write_result_json)

    prep, scan, res = inspected
    stamp = _re.compile(r"generated \S+ by")  # the HTML says when it was drawn
    html_path = write_html_report(res, prep, scan, tmp_path / "r.html", max_points=2000)
    html = html_report(res, prep, scan, max_points=2000)
    assert stamp.sub("", html.decode("utf-8")) == stamp.sub("", html_path.read_text(encoding="utf-8"))
    assert png_summary(res, scan) == write_png_summary(res, scan, tmp_path / "s.png").read_bytes()
    assert png_summary(res, scan)[:8] == b"\x89PNG\r\n\x1a\n"
    assert colored_ply(res, scan) == write_colored_ply(res, scan, tmp_path / "d.ply").read_bytes()
    ply = read_ply_full(colored_ply(res, scan, binary=False))
    np.testing.assert_array_equal(ply.properties["deviation"], res.deviations.values)
    data = result_json(res, timings={"read_scan_s": 0.25})
    assert data == write_result_json(res, tmp_path / "r.json", timings={"read_scan_s": 0.25}).read_bytes()
    d = json.loads(data)
    assert d["verdict"] == res.verdict == "fail" and d["timings"]["read_scan_s"] == 0.25
    with pytest.raises(ValueError, match="points"):
        html_report(res, prep, scan[:-3])
