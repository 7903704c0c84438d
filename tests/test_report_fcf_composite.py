"""Composite feature control frames in the reports (issue 28 item 4): ASME Y14.5 draws the two
segments of a composite frame as ONE frame -- one symbol cell spanning two rows, the upper
segment's zone and datums in the top row, the lower's below -- not two frames.  Each segment
keeps its own row of values and verdict in the table; the pair sits together, under the upper
segment's datum reference frame.

The plan is NIST CTC 04's composite position (GT2 ⌖Ø1.5 D|E|F over GT3 ⌖Ø0.3 D|E) among
ordinary frames, the lower segment written away from its upper (after a frame of its own DRF
D|E) so that keeping the pair together is tested too.
"""
from __future__ import annotations

from html.parser import HTMLParser

import pytest

from fcf_synthetic import synthetic_plan_result
from shapeverify.characteristics.plan import load_plan
from shapeverify.report import fcf as F

DATUMS = {k: {"faces": [f"face:{i}"]} for i, k in enumerate("DEF", start=1)}


def _pos(name, tol, datums, seg, pid, other, link=True):
    pmi = {"kind": "geometric_tolerance", "type": "Position", "id": pid, "value": tol,
           "zone": "Diameter"}
    if link:
        pmi["composite"] = {"segment": seg, "with": other, "entity": "#9"}
    return {"name": name, "type": "position", "features": ["hole:1", "hole:2"], "tol": tol,
            "datums": datums, "composite": seg, "pmi": pmi}


def _plan(link=True):
    return load_plan({"datums": DATUMS, "characteristics": [
        {"name": "GT1_flatness", "type": "flatness", "feature": "face:1", "tol": 0.05},
        _pos("GT2_position", 1.5, ["D", "E", "F"], "upper", "GT2", "GT3", link),
        {"name": "GT9_profile", "type": "surface_profile", "tol": 0.5,
         "datums": ["D", "E", "F"]},
        {"name": "GT7_perp", "type": "perpendicularity", "faces": ["face:5"], "tol": 0.1,
         "datums": ["D", "E"]},
        _pos("GT3_position", 0.3, ["D", "E"], "lower", "GT3", "GT2", link),
    ]})


#: the table's rows, top to bottom, when the pair is kept together
ORDER = [("head", "D|E|F"), ("row", "GT2_position"), ("row", "GT3_position"),
         ("row", "GT9_profile"), ("head", "D|E"), ("row", "GT7_perp"), ("head", ""),
         ("row", "GT1_flatness")]


@pytest.mark.parametrize("link", [True, False])
def test_composite_pair_found_by_pmi_link_or_plan_order(link):
    """``pmi.composite.with`` names the other segment's PMI id; a hand-written plan without it
    pairs a lower with the nearest upper of its type before it."""
    plan = _plan(link)
    assert F.composite_pairs(plan.characteristics) == {"GT3_position": "GT2_position"}


def test_composite_pair_not_matched_to_the_wrong_upper():
    """A lower whose link names another PMI id pairs with that one, not the nearest upper."""
    plan = load_plan({"datums": DATUMS, "characteristics": [
        _pos("A_up", 1.5, ["D", "E", "F"], "upper", "GT2", "GT3"),
        _pos("B_up", 1.0, ["D", "E", "F"], "upper", "GT4", "GT5"),
        _pos("A_lo", 0.3, ["D", "E"], "lower", "GT3", "GT2"),
        _pos("B_lo", 0.2, ["D", "E"], "lower", "GT5", "GT4")]})
    assert F.composite_pairs(plan.characteristics) == {"A_lo": "A_up", "B_lo": "B_up"}


# ------------------------------------------------------------------ HTML
class _Table(HTMLParser):
    """The characteristics table: rows (head / row name), each row's cells (tag attrs), the
    composite frames' grid cells (style) and symbols."""

    def __init__(self):
        super().__init__()
        self.rows, self.comps, self._comp, self._depth = [], [], None, 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "tr" and a.get("class") == "drf":
            self.rows.append(("head", a.get("data-drf"), []))
        elif tag == "tr" and "data-name" in a:
            self.rows.append(("row", a["data-name"], []))
        elif tag == "td":
            self.rows[-1][2].append(a)
        if self._comp is not None:
            self._depth += 1
            if self._depth == 1 and tag == "span":          # a grid cell
                self._comp["cells"].append({"style": a.get("style", ""),
                                            "class": a.get("class", ""), "svg": 0})
            if tag == "svg":
                self._comp["cells"][-1]["svg"] += 1
        elif tag == "span" and "fcf-comp" in (a.get("class") or "").split():
            self._comp = {"attrs": a, "cells": []}
            self._depth = 0

    def handle_endtag(self, tag):
        if self._comp is not None:
            if self._depth == 0:
                self.comps.append(self._comp)
                self._comp = None
            else:
                self._depth -= 1


def _grid(style):
    """``{"grid-column": "2", "grid-row": "1 / span 2"}`` of a style attribute."""
    return dict((k.strip(), v.strip()) for k, v in
                (x.split(":", 1) for x in style.split(";") if ":" in x))


def _html_table(pr):
    from shapeverify.characteristics.evaluate import format_value
    from shapeverify.report.html import _characteristics_table

    chars = [c.to_dict() for c in pr.characteristics]
    return _characteristics_table(chars, pr, lambda v, s=False: format_value(v, s))


def test_html_composite_frame_is_one_symbol_cell_spanning_both_rows():
    pr = synthetic_plan_result(_plan())
    p = _Table()
    p.feed(_html_table(pr))
    assert [r[:2] for r in p.rows] == ORDER
    rows = {r[1]: r[2] for r in p.rows if r[0] == "row"}
    # the upper's row holds the frame cell for both rows; the lower's row has one cell less
    # (its value and verdict cells as every row's)
    assert len(rows["GT2_position"]) == len(rows["GT9_profile"]) == 8
    assert len(rows["GT3_position"]) == 7
    pair = [c for c in rows["GT2_position"] if c.get("rowspan")]
    assert pair == [{"rowspan": "2", "class": "fcf-pair", "data-lower": "GT3_position"}]
    # one composite frame: one symbol, its cell spanning grid rows 1-2; the upper's zone and
    # datums D E F in row 1, the lower's Ø0.3 D E in row 2, column by column
    comp, = p.comps
    up, lo = (F.frames(c, e)[0] for c, e in zip(pr.characteristics[1::3],
                                                pr.plan.characteristics[1::3]))
    assert (up.text, lo.text) == ("⌖|Ø1.5|D|E|F", "⌖|Ø0.3|D|E")
    assert comp["attrs"]["data-fcf-upper"] == up.text
    assert comp["attrs"]["data-fcf-lower"] == lo.text
    syms = [c for c in comp["cells"] if c["svg"]]
    assert len(syms) == 1 and sum(c["svg"] for c in comp["cells"]) == 1
    assert _grid(syms[0]["style"]) == {"grid-column": "1", "grid-row": "1 / span 2"}
    filled = {(_grid(c["style"])["grid-row"], _grid(c["style"])["grid-column"])
              for c in comp["cells"] if not c["svg"] and "fcf-empty" not in c["class"]}
    assert filled == {("1", "2"), ("1", "3"), ("1", "4"), ("1", "5"),
                      ("2", "2"), ("2", "3"), ("2", "4")}
    # no separate frame for either segment
    html = _html_table(pr)
    assert html.count('class="fcf-comp"') == 1
    assert f'data-fcf="{up.text}"' not in html and f'data-fcf="{lo.text}"' not in html


def test_html_non_composite_frames_unchanged():
    """Every other row: its own cell with the frame as before (frame_html)."""
    pr = synthetic_plan_result(_plan())
    html = _html_table(pr)
    for c, e in zip(pr.characteristics, pr.plan.characteristics):
        if getattr(e, "composite", None) is None:
            fr, = F.frames(c, e)
            assert f"<td>{F.frame_html(fr)}</td>" in html, c.name


# ------------------------------------------------------------------ PDF (matplotlib)
def _pdf_pages(pr):
    from shapeverify.characteristics.pdf import _pages_table

    figs = _pages_table(pr, "CTC 04")
    for fig in figs:
        fig.canvas.draw()
    return figs


def _boxes(fig, gid):
    from matplotlib.patches import Rectangle

    r = fig.canvas.get_renderer()
    return [a.get_window_extent(r) for a in fig.findobj(Rectangle) if a.get_gid() == gid]


def test_pdf_composite_frame_is_one_symbol_cell_spanning_both_rows():
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    pr = synthetic_plan_result(_plan())
    fig, = _pdf_pages(pr)
    r = fig.canvas.get_renderer()
    up, lo = _boxes(fig, "fcf:GT2_position:0"), _boxes(fig, "fcf:GT3_position:0")
    # upper: the symbol cell and its zone, D, E, F; lower: its zone, D, E
    assert len(up) == 5 and len(lo) == 3
    h_up = {round(b.height, 1) for b in up[1:]}
    assert len(h_up) == 1
    h = h_up.pop()
    sym = max(up, key=lambda b: b.height)
    # one symbol cell: twice a row's height, from the lower row's foot to the upper's top
    assert sym.height == pytest.approx(2 * h, abs=0.2)
    assert sym.y0 == pytest.approx(min(b.y0 for b in lo), abs=0.2)
    assert sym.y1 == pytest.approx(max(b.y1 for b in up if b is not sym), abs=0.2)
    # the rows sit side by side with it: the upper above the lower, both right of the cell
    assert all(b.x0 >= sym.x1 - 0.5 for b in up if b is not sym)
    assert all(b.x0 >= sym.x1 - 0.5 for b in lo)
    assert min(b.y0 for b in up if b is not sym) == pytest.approx(max(b.y1 for b in lo), abs=0.2)
    # the columns line up: zone, D, E of the two rows start at the same x
    xs_up = sorted(b.x0 for b in up if b is not sym)[:3]
    xs_lo = sorted(b.x0 for b in lo)
    assert xs_up == pytest.approx(xs_lo, abs=0.2)
    # the position symbol drawn once (its strokes), inside the cell
    strokes = [a for a in fig.findobj(lambda a: isinstance(a, (Line2D, Polygon)))
               if (a.get_gid() or "").startswith("fcf:GT") and "position" in a.get_gid()]
    assert len(strokes) == len(F.STROKES["⌖"])
    for a in strokes:
        bb = a.get_window_extent(r)
        assert sym.x0 - 0.5 <= bb.x0 and bb.x1 <= sym.x1 + 0.5
        assert sym.y0 - 0.5 <= bb.y0 and bb.y1 <= sym.y1 + 0.5


def test_pdf_non_composite_frames_unchanged_and_pair_kept_together():
    from matplotlib.text import Text

    from shapeverify.characteristics.pdf import _table_entries

    pr = synthetic_plan_result(_plan())
    got = [("head", "|".join(e[1])) if e[0] == "head" else ("row", e[1][0][0])
           for e in _table_entries(pr)]
    assert got == ORDER
    fig, = _pdf_pages(pr)
    r = fig.canvas.get_renderer()
    for c, e in zip(pr.characteristics, pr.plan.characteristics):
        if getattr(e, "composite", None) is not None:
            continue
        fr, = F.frames(c, e)
        boxes = _boxes(fig, f"fcf:{c.name}:0")
        assert len(boxes) == len(fr.compartments), c.name     # one row of boxes, as before
        assert len({round(b.y0, 1) for b in boxes}) == 1
        texts = sorted((a for a in fig.findobj(Text) if a.get_gid() == f"fcf:{c.name}:0"),
                       key=lambda a: a.get_window_extent(r).x0)
        want = [F.font_text(v) for comp in fr.compartments for k, v in comp
                if k in ("text", "circled")]
        assert [t.get_text() for t in texts] == want
