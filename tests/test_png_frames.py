"""The PNG summary shows each characteristic's feature control frame (issue 28 item 4), grouped
by datum reference frame as the HTML and PDF reports, without a glyph its font lacks and without
clipping.

The inspection is real (``test_report_layout._inspected``: a 300 mm plane with a dent); its
characteristics are the synthetic evaluation of a NIST FTC 06 plan
(``tests/data/pmi_plans/png_ftc_06_42.yaml``, 42 characteristics in 7 DRF groups), so the frames are the drawing's.  What is checked is read
back from the figure: its texts and the artists of each frame (gid ``png-fcf:NAME:i``), placed
by matplotlib's renderer.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from fcf_synthetic import synthetic_plan_result
from shapeverify.report import fcf as F
from shapeverify.report.png import summary_figure
from shapeverify.report.png_frames import (MAX_COLUMNS, MAX_PER_COLUMN, panel_columns,
                                           panel_entries)
from test_report_layout import _inspected

PLANS = Path(__file__).parent / "data" / "pmi_plans"


@pytest.fixture(scope="module")
def drawn():
    res, scan = _inspected(300.0, "SN-0042")
    pr = synthetic_plan_result(PLANS / "png_ftc_06_42.yaml")
    res = dataclasses.replace(res, characteristics=pr.characteristics, plan=pr)
    fig = summary_figure(res, scan)
    fig.canvas.draw()
    return res, fig, fig.canvas.get_renderer()


def _panel_texts(fig):
    return [t for t in fig.texts if t.get_gid() == "characteristics"]


def _frame_artists(fig):
    """``{(name, i): [artists]}`` of the frames drawn by the panel."""
    out = {}
    for a in fig.findobj(lambda a: (a.get_gid() or "").startswith("png-fcf:")):
        head, i = a.get_gid().rsplit(":", 1)
        out.setdefault((head[len("png-fcf:"):], int(i)), []).append(a)
    return out


def test_png_summary_shows_each_feature_control_frame(drawn):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon, Rectangle
    from matplotlib.text import Text

    res, fig, r = drawn
    entries = {e.name: e for e in res.plan.plan.characteristics}
    arts = _frame_artists(fig)
    want = {(c.name, i): f for c in res.characteristics
            for i, f in enumerate(F.frames(c, entries[c.name]))}
    assert set(arts) == set(want)                     # every frame of every characteristic
    assert len(want) == 42
    for key, f in want.items():
        texts = sorted((a for a in arts[key] if isinstance(a, Text)),
                       key=lambda a: a.get_window_extent(r).x0)
        tokens = [v for c in f.compartments for k, v in c if k in ("text", "circled")]
        assert [t.get_text() for t in texts][:len(tokens)] == [F.font_text(v) for v in tokens]
        strokes = [a for a in arts[key] if isinstance(a, (Line2D, Polygon))]
        assert len(strokes) == (len(F.STROKES[f.symbol]) if f.is_tolerance else 0), key
        boxes = [a for a in arts[key] if isinstance(a, Rectangle)]
        assert len(boxes) == (len(f.compartments) if f.is_tolerance else 0), key
    # the frame of a position with its modifier and datums, as FTC 06 writes it
    gt4 = F.frames(next(c for c in res.characteristics if c.name == "GT4_position"),
                   entries["GT4_position"])[0]
    assert gt4.text == "⌖|Ø0.381|E|A|B"
    assert [t.get_text() for t in sorted((a for a in arts[("GT4_position", 0)]
                                          if isinstance(a, Text)),
                                         key=lambda a: a.get_window_extent(r).x0)] == \
        ["Ø", "0.381", "E", "A", "B"]


def test_png_summary_groups_the_frames_by_datum_reference_frame(drawn):
    res, fig, r = drawn
    entries = {e.name: e for e in res.plan.plan.characteristics}
    items = [(c.name, F.frames(c, entries[c.name])) for c in res.characteristics]
    groups = F.group_by_drf(items)
    texts = _panel_texts(fig)
    titles = {F.drf_title(d) for d, _ in groups}
    # the panel read column by column, top to bottom: the headings, and each characteristic
    # where its first frame is drawn
    heads = [(t.get_window_extent(r), t.get_text()) for t in texts
             if t.get_text().removesuffix(" (continued)") in titles]
    lefts = sorted({round(bb.x0) for bb, _ in heads})

    def column(x):
        return sum(left <= x + 0.5 for left in lefts)

    marks = [(column(bb.x0), -bb.y0, "head", s) for bb, s in heads]
    for (name, i), arts in _frame_artists(fig).items():
        if i == 0:
            bb = [a.get_window_extent(r) for a in arts]
            marks.append((column(min(b.x0 for b in bb)), -min(b.y0 for b in bb), "row", name))
    order = [m[2:] for m in sorted(marks)]
    got = [o for o in order if not (o[0] == "head" and o[1].endswith("(continued)"))]
    want = []
    for drf, group in groups:
        want.append(("head", F.drf_title(drf)))
        want += [("row", n) for n, _ in group]
    assert got == want
    assert len(groups) == 7 and sum(o[0] == "row" for o in got) == 42
    # measured value and verdict on each line, units stated in the title
    title = next(t.get_text() for t in texts if t.get_text().startswith("Characteristics"))
    assert "(42)" in title and "in mm" in title
    shown = [t.get_text() for t in texts]
    gt4 = next(c for c in res.characteristics if c.name == "GT4_position")
    assert f"{gt4.measured:.4f}" in shown and gt4.verdict in shown


def test_png_summary_text_uses_only_glyphs_its_font_has(drawn):
    """DejaVu Sans lacks ⌖ ⌭ ⌒ ⌓ ⌰ ⏤ ⌯ and Ⓜ Ⓕ: the frames' symbols are strokes, the texts
    take only characters of the font each text is drawn with (no tofu box)."""
    from matplotlib import font_manager
    from matplotlib.ft2font import FT2Font
    from matplotlib.text import Text

    _, fig, _ = drawn
    charmaps = {}
    texts = [t for t in fig.findobj(Text) if t.get_text().strip()]
    assert len(texts) > 200
    for t in texts:
        path = font_manager.findfont(t.get_fontproperties(), fallback_to_default=True)
        cmap = charmaps.setdefault(path, set(FT2Font(path).get_charmap()))
        missing = {ch for ch in t.get_text() if ch != "\n" and ord(ch) not in cmap}
        assert not missing, (t.get_text(), missing, path)
    assert not any(F._font_has(s) for s in ("⌖", "⌓", "Ⓜ"))     # why strokes are needed


def test_png_summary_characteristics_fit_inside_the_figure_and_their_columns(drawn):
    from matplotlib.text import Text

    res, fig, r = drawn
    W, H = fig.bbox.width, fig.bbox.height
    texts = _panel_texts(fig)
    panel = texts + [a for arts in _frame_artists(fig).values() for a in arts]
    for a in panel:
        bb = a.get_window_extent(r)
        assert bb.x0 >= -0.5 and bb.x1 <= W + 0.5 and bb.y0 >= -0.5 and bb.y1 <= H + 0.5, a
    # no text of the panel runs into another one (the frame's circled letters lie inside
    # their circles, not on another text)
    boxes = [(t.get_text(), t.get_window_extent(r)) for t in texts]
    boxes += [(a.get_text(), a.get_window_extent(r)) for arts in _frame_artists(fig).values()
              for a in arts if isinstance(a, Text)]
    def overlap(a, b):            # touching (a frame's Ø and its value) is not overlapping
        return min(a.x1, b.x1) - max(a.x0, b.x0) > 0.5 and min(a.y1, b.y1) - max(a.y0, b.y0) > 0.5

    for i, (s, bb) in enumerate(boxes):
        for u, cc in boxes[i + 1:]:
            assert not overlap(bb, cc), (s, u)
    # the panel lies below everything else: the histogram's label and the right-hand column
    top = max(a.get_window_extent(r).y1 for a in panel)
    others = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()
              and t.get_gid() != "characteristics"
              and not (t.get_gid() or "").startswith("png-fcf:") and t.axes is not None
              and t.axes.get_visible()]
    hist = next(a for a in fig.axes if a.get_ylabel() == "points")
    assert hist.xaxis.label.get_window_extent(r).y0 > top
    for t in others:
        if t.get_window_extent(r).width > 0:
            assert t.get_window_extent(r).y0 > top, t.get_text()[:40]
    # each frame stays in its column: left of the next column's first text
    lefts = sorted({round(t.get_window_extent(r).x0) for t in texts
                    if t.get_text().startswith("DRF")})
    for arts in _frame_artists(fig).values():
        x0 = min(a.get_window_extent(r).x0 for a in arts)
        x1 = max(a.get_window_extent(r).x1 for a in arts)
        nxt = [x for x in lefts if x > x0]
        assert not nxt or x1 < nxt[0]


def test_png_summary_without_a_plan_has_no_characteristics_panel(drawn):
    res, _, _ = drawn
    fig = summary_figure(dataclasses.replace(res, characteristics=(), plan=None))
    assert fig.get_figheight() == pytest.approx(8.6)
    assert not _panel_texts(fig) and not _frame_artists(fig)


def test_a_long_plan_lists_what_fits_and_counts_the_rest():
    """More characteristics than the panel holds: the last line counts the ones left out,
    and every characteristic is either listed or counted (never lost silently)."""
    pr = synthetic_plan_result(PLANS / "png_ftc_06_42.yaml")
    many = tuple(dataclasses.replace(c, name=f"{c.name}_{k}") for k in range(3)
                 for c in pr.characteristics)
    res = type("R", (), {"characteristics": many,
                         "plan": dataclasses.replace(pr, plan=pr.plan.model_copy(update={
                             "characteristics": [e.model_copy(update={"name": f"{e.name}_{k}"})
                                                 for k in range(3)
                                                 for e in pr.plan.characteristics]}))})()
    entries = panel_entries(res)
    cols, left = panel_columns(entries)
    assert len(cols) == MAX_COLUMNS and all(len(c) <= MAX_PER_COLUMN for c in cols)
    assert cols[-1][-1] == ("more", left)
    listed = {e[1].name for c in cols for e in c if e[0] == "row"}
    assert left > 0 and len(listed) + left == len(many) == 126
    # the short FTC 06 plan itself fits whole
    cols, left = panel_columns(panel_entries(
        type("R", (), {"characteristics": pr.characteristics, "plan": pr})()))
    assert left == 0
    assert {e[1].name for c in cols for e in c if e[0] == "row"} == \
        {c.name for c in pr.characteristics}


def test_a_long_plan_of_holes_counts_each_hole_once():
    """A hole takes two lines (size, position): one cut between them is listed, not counted."""
    from shapeverify.characteristics.plan import load_plan

    plan = load_plan({"characteristics": [
        {"name": f"H{i}", "type": "hole", "feature": "hole:1", "diameter": {"tol": 0.05},
         "position": {"tol": 0.5}} for i in range(40)]})
    pr = synthetic_plan_result(plan)
    cols, left = panel_columns(panel_entries(
        type("R", (), {"characteristics": pr.characteristics, "plan": pr})()))
    listed = {e[1].name for c in cols for e in c if e[0] == "row"}
    assert left > 0 and len(listed) + left == 40
    assert all(len(c) <= MAX_PER_COLUMN for c in cols)
