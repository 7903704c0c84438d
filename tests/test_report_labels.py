"""Region labels never overlap (issue 29 item 1): "Labels pile up in the reports" -- ten regions
of one dent were all labelled at "(0.2, 0.6, 1.1)".  Each label now sits on a leader line where
its drawn box (matplotlib's own extent) meets no other label and stays inside its plot; a label
with no free place is left out of the picture (its region stays in the numbered list)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.inspection import inspect_registered
from shapeverify.report.labels import OFFSETS, boxes_overlap, free_labels, place_labels
from shapeverify.report.png import summary_figure
from test_report_layout import ScaledPlane


def _label_boxes(fig):
    from matplotlib.text import Annotation

    from shapeverify.report.labels import _text_box

    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    return [(a, _text_box(a, r)) for a in fig.findobj(Annotation)
            if a.get_visible() and a.get_text().startswith("R")]


def _assert_apart_and_inside(boxes):
    for i, (a, b) in enumerate(boxes):
        frame = a.axes.bbox
        assert frame.x0 - 0.5 <= b[0] and b[2] <= frame.x1 + 0.5, a.get_text()
        assert frame.y0 - 0.5 <= b[1] and b[3] <= frame.y1 + 0.5, a.get_text()
        for c, d in boxes[i + 1:]:
            if c.axes is a.axes:
                assert not boxes_overlap(b, d), (a.get_text(), c.get_text(), b, d)


def test_many_close_anchors_get_labels_that_do_not_overlap():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5, 4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    rng = np.random.default_rng(0)
    ax.scatter(rng.uniform(0, 100, 2000), rng.uniform(0, 80, 2000), s=1)
    anchors = rng.normal([50, 40], 3.0, size=(40, 2))         # 40 regions in 6 % of the plot
    placed = place_labels(ax, anchors, [f"R{i + 1}" for i in range(40)])
    boxes = _label_boxes(fig)
    assert len(boxes) == len(placed)
    assert 8 <= len(placed) < 40              # many find a place; the rest are left out
    assert [i for i, _ in placed][:1] == [0]  # the most severe is always labelled
    _assert_apart_and_inside(boxes)
    # well apart, every one is labelled at the first (closest) offset
    fig2 = Figure(figsize=(5, 4), dpi=100)
    FigureCanvasAgg(fig2)
    ax2 = fig2.add_subplot()
    ax2.scatter([0, 100], [0, 80], s=1)
    far = [(20, 20), (50, 40), (80, 60)]
    placed = place_labels(ax2, far, ["R1", "R2", "R3"])
    assert [i for i, _ in placed] == [0, 1, 2]
    assert all(tuple(a.xyann) == OFFSETS[0] for _, a in placed)


def test_free_labels_keeps_the_first_of_overlapping_ones():
    xy = [(0, 0), (10, 3), (30, 0), (31, 9), (60, 0)]
    assert free_labels(xy, [25] * 5, 10) == [0, 2, 4]


def _many_dents(L: float = 300.0, rows: int = 3, cols: int = 4):
    """A plane with rows x cols separate dents 7 % of L apart (one region each)."""
    prep = ScaledPlane(L)
    tol = L / 500
    h = L / 160
    x, y = np.meshgrid(np.arange(h, L - h, h), np.arange(h, 0.6 * L - h, h))
    x, y = x.ravel(), y.ravel()
    z = np.random.default_rng(3).normal(0, tol / 10, x.size)
    for r in range(rows):
        for c in range(cols):
            cx, cy = (0.3 + 0.07 * c) * L, (0.17 + 0.07 * r) * L
            z -= (3 + 0.1 * (r * cols + c)) * tol * np.exp(
                -((x - cx) ** 2 + (y - cy) ** 2) / (0.015 * L) ** 2)
    scan = np.column_stack([x, y, z])
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=tol / 10, iterations=8, converged=True,
                          inlier_fraction=0.97, weights=np.ones(len(scan)), message="")
    return inspect_registered(prep, scan, reg, tolerance=tol), scan


def test_png_summary_region_labels_do_not_overlap_with_many_close_regions():
    res, scan = _many_dents()
    assert len(res.regions) >= 10, len(res.regions)
    fig = summary_figure(res, scan)
    boxes = _label_boxes(fig)
    _assert_apart_and_inside(boxes)
    per_axes = {}
    for a, _ in boxes:
        per_axes.setdefault(id(a.axes), []).append(a.get_text())
    assert len(per_axes) == 2                       # both views are labelled
    for texts in per_axes.values():
        assert "R1" in texts and len(texts) >= 4, texts
