"""Report layout (issue 32, item 4): nothing clipped in the PNG summary at any part size or text
length -- the right-hand text column and the banner were cut ("inlier", "195 pt",
"within_tolerance") -- and lengths and areas keep three significant digits (a 1 mm part's
region printed "area 0.0 mm²").

The inspections are real (``inspect_registered``) on an analytic plane of any size with exact
closest points; the text extents are matplotlib's own (``get_window_extent`` after drawing).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.inspection import inspect_registered
from shapeverify.report.png import summary_figure


class ScaledPlane:
    """A prepared-model stand-in: the rectangle [0, L] x [0, 0.6 L] in z = 0 (two faces)."""

    def __init__(self, L: float):
        W = 0.6 * L
        self.L, self.W = L, W
        faces = []
        for x0, x1 in ((0.0, L / 2), (L / 2, L)):
            ctrl = np.array([[[x0, 0, 0], [x0, W, 0]], [[x1, 0, 0], [x1, W, 0]]], float)
            loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
            free = np.array([True, x1 == L, True, x0 == 0])
            faces.append(Face(NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl), (loop,),
                              (free,)))
        self.model = Model(tuple(faces), source=f"plane {L} mm")
        h = L / 100
        x, y = np.meshgrid(np.arange(h / 2, L, h), np.arange(h / 2, W, h))
        pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
        self.points = SimpleNamespace(points=pts, face=(pts[:, 0] > L / 2).astype(np.int32),
                                      spacing=h)
        self.spacing, self.n_points = h, len(pts)

    def closest(self, q, exact=False):
        foot = q.copy()
        foot[:, 0] = np.clip(q[:, 0], 0, self.L)
        foot[:, 1] = np.clip(q[:, 1], 0, self.W)
        foot[:, 2] = 0.0
        d = np.linalg.norm(q - foot, axis=1) * np.where(q[:, 2] >= 0, 1.0, -1.0)
        return SimpleNamespace(points=foot, normals=np.tile([0.0, 0.0, 1.0], (len(q), 1)),
                               distances=d, face=(foot[:, 0] > self.L / 2).astype(np.int32),
                               uv=foot[:, :2], index=np.zeros(len(q), np.int64),
                               on_boundary=(foot[:, 0] != q[:, 0]) | (foot[:, 1] != q[:, 1]))


def _inspected(L: float, part: str, dent: bool = True):
    """A scan of the plane of length ``L`` mm with a dent of 2 tolerances (a 1/500 of L tolerance)."""
    prep = ScaledPlane(L)
    tol = L / 500
    rng = np.random.default_rng(3)
    h = L / 160
    x, y = np.meshgrid(np.arange(h, L - h, h), np.arange(h, 0.6 * L - h, h))
    x, y = x.ravel(), y.ravel()
    z = rng.normal(0, tol / 10, x.size)
    if dent:
        z -= 2 * tol * np.exp(-((x - 0.3 * L) ** 2 + (y - 0.2 * L) ** 2) / (0.03 * L) ** 2)
    scan = np.column_stack([x, y, z])
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=tol / 10, iterations=8, converged=True,
                          inlier_fraction=0.97, weights=np.ones(len(scan)), message="")
    res = inspect_registered(prep, scan, reg, tolerance=tol)
    res.inputs.update(part=part, scan=f"{part}-scan.ply", model=f"{part}.svm")
    return res, scan


def _text_extents(fig):
    from matplotlib.text import Text

    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    # tick labels: matplotlib keeps those of ticks outside the view (not drawn); what is drawn
    # of them is in the figure's tight bounding box, checked separately
    ticks = {id(lab) for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
             for tick in axis.get_major_ticks() + axis.get_minor_ticks()
             for lab in (tick.label1, tick.label2)}
    return r, [(t, t.get_window_extent(r)) for t in fig.findobj(Text)
               if t.get_visible() and t.get_text().strip() and id(t) not in ticks]


LONG_ID = "SN-" + "0123456789ABCDEF" * 16          # 259 characters


@pytest.mark.parametrize("L, part, dent", [(40_000.0, LONG_ID, True), (1.0, LONG_ID, True),
                                           (300.0, "SN-0042", False), (300.0, LONG_ID, True)])
def test_png_summary_text_stays_inside_the_figure_and_the_banner(L, part, dent):
    res, scan = _inspected(L, part, dent)
    assert res.verdict == ("fail" if dent else "pass")
    fig = summary_figure(res, scan)
    r, texts = _text_extents(fig)
    W, H = fig.bbox.width, fig.bbox.height
    # everything drawn lies inside the figure
    tight = fig.get_tightbbox(r)
    assert tight.x0 >= -0.01 and tight.y0 >= -0.01
    assert tight.x1 <= fig.get_figwidth() + 0.01 and tight.y1 <= fig.get_figheight() + 0.01
    for t, bb in texts:
        assert bb.x0 >= -0.5 and bb.x1 <= W + 0.5 and bb.y0 >= -0.5 and bb.y1 <= H + 0.5, t.get_text()
    # the banner's texts stay inside the banner and the verdict does not run into them
    banner = fig.axes[0]
    inside = [(t, bb) for t, bb in texts if t.axes is banner]
    assert len(inside) == 4
    box = banner.bbox
    for t, bb in inside:
        assert box.x0 - 0.5 <= bb.x0 and bb.x1 <= box.x1 + 0.5, t.get_text()
        assert box.y0 - 0.5 <= bb.y0 and bb.y1 <= box.y1 + 0.5, t.get_text()
    verdict = next(bb for t, bb in inside if t.get_text() == res.verdict.upper())
    assert all(verdict.x1 < bb.x0 for t, bb in inside if t.get_text() != res.verdict.upper())
    # every text is still readable: at least 7 pt; no two texts overlap (the colour bar's
    # label ran into the statistics of a 1 mm part)
    assert min(t.get_fontsize() for t, _ in texts) >= 7.0
    for i, (t, bb) in enumerate(texts):
        for u, cc in texts[i + 1:]:
            assert not bb.overlaps(cc), (t.get_text()[:40], u.get_text()[:40])
    # what the right-hand column must say is there in full
    column = "\n".join(t.get_text() for t, _ in texts)
    assert "inliers" in column and "pts" in column or not dent
    assert f"rule: {res.rule}" in column


def test_a_one_mm_parts_region_area_keeps_three_significant_digits():
    res, scan = _inspected(1.0, "SN-1")
    area = res.regions[0].area
    assert 0 < area < 0.01                         # would print "0.0 mm²"
    _, texts = _text_extents(summary_figure(res, scan))
    column = "\n".join(t.get_text() for t, _ in texts)
    from shapeverify.quantities import area_text

    shown = area_text(area)
    assert shown.endswith("µm²") and shown in column
    value = float(shown.split()[0].replace(",", ""))
    assert value == pytest.approx(area * 1e6, rel=5e-3)


def test_png_histogram_axis_covers_every_evaluated_inlier():
    res, scan = _inspected(300.0, "SN-2")
    fig = summary_figure(res, scan)
    hist = next(a for a in fig.axes if a.get_ylabel() == "points")
    lo, hi = hist.get_xlim()
    assert lo <= res.statistics.min and hi >= res.statistics.max


@pytest.mark.slow
def test_html_report_of_a_40k_point_scan_is_under_3_mb_and_keeps_every_measurement(tmp_path):
    """6-7 MB before (4.8 MB of it plotly.js, every point drawn and every value sent for the
    histogram); what is measured is all still in the page's tables."""
    from shapeverify.report import write_html_report

    prep = ScaledPlane(300.0)
    h = 1.16
    x, y = np.meshgrid(np.arange(h, 300 - h, h), np.arange(h, 180 - h, h))
    x, y = x.ravel(), y.ravel()
    z = np.random.default_rng(1).normal(0, 0.02, x.size)
    z -= 0.4 * np.exp(-((x - 90) ** 2 + (y - 60) ** 2) / 100.0)
    scan = np.column_stack([x, y, z])
    assert 39_000 < len(scan) < 41_000
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=0.02, iterations=8, converged=True,
                          inlier_fraction=0.97, weights=np.ones(len(scan)), message="")
    res = inspect_registered(prep, scan, reg, tolerance=0.2)
    page = write_html_report(res, prep, scan, tmp_path / "r.html").read_text(encoding="utf-8")
    assert len(page.encode("utf-8")) < 3_000_000
    dev = res.deviations
    assert f"shows 20,000 of {dev.n_evaluated:,} evaluated points" in page
    assert f"{dev.n_evaluated:,}" in page                              # the statistics: all
    assert f"Histogram of {dev.n_evaluated:,} evaluated deviations" in page
    assert f"{res.statistics.min:+.4f}" in page and f"{res.statistics.max:+.4f}" in page
