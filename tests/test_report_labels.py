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


def test_html_view_opens_on_the_whole_part_centred_on_the_worst_region_and_not_edge_on():
    """The hammer is 40 m long: the old camera (eye 1.5, 1.5, 1.4) cut it off and saw a dent
    on its side face edge-on.  Here: a 40 m x 2 m x 1 m bar with a dent on its +y side."""
    from shapeverify.report.html import scene_camera, view_projection

    rng = np.random.default_rng(2)
    P = rng.uniform([0, 0, 0], [40_000, 2_000, 1_000], size=(5000, 3))
    dent, normal = np.array([31_000.0, 2_000.0, 500.0]), np.array([0.0, 1.0, 0.0])
    camera, project = scene_camera(np.vstack([P, dent]), (dent, normal))
    eye = np.array([camera["eye"][k] for k in "xyz"])
    centre = np.array([camera["center"][k] for k in "xyz"])
    view = (eye - centre) / np.linalg.norm(eye - centre)
    # looking at the dent from its outward side, 25 degrees off its normal
    assert np.degrees(np.arccos(view @ normal)) == pytest.approx(25.0, abs=1e-6)
    # the dent is in the middle of the view, the whole bar in view
    assert np.allclose(project(dent[None]), [[450.0, 320.0]], atol=1e-6)
    corners = np.array([[x, y, z] for x in (0, 40_000) for y in (0, 2_000) for z in (0, 1_000)])
    xy = project(corners)
    assert np.all((xy >= 0) & (xy <= [900, 640])), xy
    # the old camera (eye 1.5, 1.5, 1.4 about the box's centre) cut the bar off
    old = dict(eye=dict(x=1.5, y=1.5, z=1.4), center=dict(x=0, y=0, z=0), up=dict(x=0, y=0, z=1))
    xy = view_projection(np.vstack([P, dent]), old)(corners)
    assert not np.all((xy >= 0) & (xy <= [900, 640]))


def test_html_labels_of_close_regions_do_not_overlap(tmp_path):
    pytest.importorskip("plotly")
    from shapeverify.report.html import _figure_3d, scene_camera, _worst
    from shapeverify.report.labels import boxes_overlap

    res, scan = _many_dents()
    fig = _figure_3d(res, None, np.flatnonzero(res.deviations.evaluated), 1.0)
    tr = next(t for t in fig.data if t.name and t.name.startswith("regions"))
    shown = [i for i, t in enumerate(tr.text) if t]
    assert 1 <= len(shown) < len(res.regions) and shown[0] == 0
    assert list(tr.hovertext) == [f"R{i + 1} {g.extreme:+.3f}" for i, g in enumerate(res.regions)]
    # the same camera and projection as the page: the drawn labels' boxes are apart
    c = np.array([g.centroid for g in res.regions])
    pts = np.vstack([res.deviations.points_model[res.deviations.evaluated], c])
    camera, project = scene_camera(pts, _worst(res))
    assert fig.layout.scene.camera.eye.x == pytest.approx(camera["eye"]["x"])
    xy = project(c)
    boxes = [(x - 0.31 * 11 * len(tr.text[i]), y + 6, x + 0.31 * 11 * len(tr.text[i]), y + 20.3)
             for i, (x, y) in enumerate(xy) if i in shown]
    for i, b in enumerate(boxes):
        assert all(not boxes_overlap(b, d) for d in boxes[i + 1:])


# ------------------------------------------------------------------ the PDF report (issue 32 item 4)
def _plan_result(L: float, part: str, n_chars: int = 30):
    """A plan result of a real inspection of a part ``L`` mm long, with ``n_chars``
    characteristics of every kind of value (floats, a hole's dicts, a long name)."""
    import dataclasses

    from shapeverify.characteristics.evaluate import CharacteristicResult
    from shapeverify.inspection.plan_link import plan_result_of
    from test_report_layout import _inspected

    res, scan = _inspected(L, part)
    pr = plan_result_of(res)
    chars = []
    for i in range(n_chars):
        if i % 3 == 0:
            chars.append(CharacteristicResult(
                f"H{i}", "hole", {"center": [0.7 * L, 0.3 * L, 0.0], "diameter": 0.06 * L},
                {"center": [0.7 * L + 0.001, 0.3 * L, 0.0], "diameter": 0.06 * L - 0.002},
                {"diameter": -0.002, "position": 0.002}, {"diameter": -0.005, "position": 0.0},
                {"diameter": 0.005, "position": 0.01}, {"diameter": 0.001, "position": 0.001},
                "pass"))
        else:
            name = part if i == 1 else f"PROFILE-{i}"
            chars.append(CharacteristicResult(name, "surface_profile", 0.0, 0.0123 * L,
                                              0.0123 * L, None, 0.02 * L, 0.0004 * L,
                                              "fail" if i == 2 else "pass"))
    return dataclasses.replace(pr, characteristics=tuple(chars)), res


def _inside(bb, box, pad=0.6):
    return (bb.x0 >= box.x0 - pad and bb.x1 <= box.x1 + pad and bb.y0 >= box.y0 - pad
            and bb.y1 <= box.y1 + pad)


@pytest.mark.slow
@pytest.mark.parametrize("L", [40_000.0, 1.0])
def test_pdf_pages_keep_every_text_inside_a4_and_the_table_readable(L):
    from matplotlib.text import Text

    from shapeverify.characteristics.pdf import pdf_figures
    from test_report_layout import LONG_ID

    pr, res = _plan_result(L, LONG_ID)
    figs = pdf_figures(pr, part=LONG_ID, scan_file=f"{LONG_ID}.ply", model_file="m.svm",
                       date="2026-12-06", tolerance=res.tolerance.max_abs,
                       regions=res.regions)
    assert len(figs) == 3                             # the map and two table pages (30 rows)
    for fig in figs:
        assert (fig.get_figwidth(), fig.get_figheight()) == pytest.approx((8.27, 11.69))
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        page = fig.bbox
        ticks = {id(lab) for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
                 for tick in axis.get_major_ticks() for lab in (tick.label1, tick.label2)}
        for t in fig.findobj(Text):
            if t.get_visible() and t.get_text().strip() and id(t) not in ticks:
                assert _inside(t.get_window_extent(r), page), t.get_text()[:60]
    # the map: every region labelled where it can be, R1 always; the list beneath names them
    texts = [t.get_text() for t in figs[0].findobj(Text)]
    assert "R1" in texts and any(t.startswith("R1  ") for x in texts for t in x.split("\n"))
    _assert_apart_and_inside(_label_boxes(figs[0]))
    # the tables: 8.5 pt, every cell's text inside its cell
    for fig in figs[1:]:
        r = fig.canvas.get_renderer()
        tab = next(a for a in fig.axes if a.tables).tables[0]
        for cell in tab.get_celld().values():
            assert cell.get_text().get_fontsize() >= 8.5
            assert _inside(cell.get_text().get_window_extent(r), cell.get_window_extent(r)), \
                cell.get_text().get_text()



def test_pdf_histogram_axis_covers_the_minimum_beyond_three_band_widths():
    """The PDF's histogram axis stopped at -0.3 (three band widths) while the minimum was
    -0.40: here a dent of 1.2 mm under a 0.2 mm band; the axis must reach the data's min and
    max, and the bars count every deviation."""
    pr, res = _plan_result(300.0, "SN-7", n_chars=3)
    dv = np.asarray(pr.deviations, float)
    dv = dv[np.isfinite(dv)]
    assert dv.min() < -3 * 0.2                         # beyond where the old axis stopped
    from shapeverify.characteristics.pdf import pdf_figures

    fig = pdf_figures(pr, part="SN-7", date="2026-12-06", tolerance=0.2)[0]
    hx = next(a for a in fig.axes if a.get_ylabel() == "points")
    lo, hi = hx.get_xlim()
    assert lo <= dv.min() and hi >= dv.max()
    assert sum(p.get_height() for p in hx.patches) == dv.size
