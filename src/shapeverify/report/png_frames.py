"""The PNG summary's characteristics panel (issue 28 item 4): each characteristic of the plan
with its feature control frame(s) as the drawing writes them, grouped by datum reference frame
as in the HTML and PDF reports.

A line is ``NAME  [frame]  measured  verdict``; a hole's size and position frames take a line
each.  The frames are drawn by :func:`shapeverify.report.fcf.draw_frame` (the symbols as
strokes, circled letters as circles: matplotlib's DejaVu Sans lacks ⌖ ⌭ ⌒ ⌓ ⌰ ⏤ and Ⓜ), and
every text goes through :func:`shapeverify.report.fcf.font_text`, so no glyph the font lacks is
asked for.  The lines fill up to :data:`MAX_COLUMNS` columns of at most
:data:`MAX_PER_COLUMN` lines; a column that starts inside a DRF group repeats its heading
("(continued)"); characteristics beyond that are counted on the last line ("… and N more").
Every text is cut with "…" to its field and a frame wider than its field is drawn smaller (down
to :data:`MIN_FRAME_FONT` points), so nothing leaves the panel.
"""
from __future__ import annotations

import math

from .fcf import (composite_pairs, draw_frame, drf_title, font_text, frame_width, frames,
                  group_by_drf)

__all__ = ["panel_entries", "panel_columns", "panel_height", "draw_panel", "MAX_COLUMNS",
           "MAX_PER_COLUMN"]

LINE = 13.0             # points per line
TITLE = 20.0            # points: the panel's title line
FONT = 7.5
FRAME_H = 10.5
MIN_FRAME_FONT = 5.5
MAX_COLUMNS = 3
MAX_PER_COLUMN = 18
_GAP = 14.0             # points between columns
_MAX_COLUMN = 330.0     # points: a column's widest
_FIELDS = (0.34, 0.44, 0.22)        # name, frame, value + verdict: fractions of a column
_VERDICT_COLOURS = {"pass": "#1b7f3b", "fail": "#b3261e", "undecided": "#a15c00"}


def panel_entries(result) -> list:
    """``[("head", datums, continued) | ("row", characteristic, frame, i), ...]``: the
    result's characteristics grouped by DRF (:func:`~shapeverify.report.fcf.group_by_drf`), one
    line per frame (``i``: the frame's index in its characteristic); ``[]`` without a plan."""
    chars = tuple(getattr(result, "characteristics", None) or ())
    if not chars:
        return []
    plan = getattr(getattr(result, "plan", None), "plan", None)
    entries = {e.name: e for e in getattr(plan, "characteristics", None) or ()}
    items = [(c, frames(c, entries.get(c.name))) for c in chars]
    out = []
    # a composite frame's lower segment on the line after its upper, in the upper's group
    for drf, group in group_by_drf(items, follows=composite_pairs(entries.values()),
                                   name=lambda it: it[0].name):
        out.append(("head", drf, False))
        for c, fs in group:
            out += [("row", c, f, i) for i, f in enumerate(fs)]
    return out


def _fill(entries, per_column: int, n_columns: int):
    """The entries in columns of ``per_column`` lines; returns ``(columns, rest)``: ``rest``
    the entries that did not fit."""
    cols, col, drf = [], [], ()
    for k, e in enumerate(entries):
        # a heading does not stand alone at a column's foot
        full = len(col) >= per_column or (e[0] == "head" and len(col) >= per_column - 1)
        if full:
            cols.append(col)
            col = []
            if len(cols) == n_columns:
                return cols, entries[k:]
            if e[0] == "row":
                col.append(("head", drf, True))
        if e[0] == "head":
            drf = e[1]
        col.append(e)
    return cols + [col], []


def panel_columns(entries, max_columns: int = MAX_COLUMNS,
                  max_per_column: int = MAX_PER_COLUMN) -> tuple[list, int]:
    """The panel's columns (lists of entries) and the number of characteristics left out
    (their names are on the last line).  As few lines per column as hold every entry in
    ``max_columns`` columns; at most ``max_per_column``."""
    if not entries:
        return [], 0
    n_cols = min(max_columns, max(1, math.ceil(len(entries) / 8)))
    for per in range(max(2, math.ceil(len(entries) / n_cols)), max_per_column + 1):
        cols, rest = _fill(entries, per, n_cols)
        if not rest:
            return cols, 0
    cols, rest = _fill(entries, max_per_column, n_cols)
    last = cols[-1]
    # the last line says how many characteristics are not listed
    while last and (len(last) >= max_per_column or last[-1][0] == "head"):
        rest.insert(0, last.pop())
    shown = {id(e[1]) for c in cols for e in c if e[0] == "row"}
    left = {id(e[1]) for e in rest if e[0] == "row"} - shown    # a hole half shown is shown
    last.append(("more", len(left)))
    return cols, len(left)


def panel_height(result) -> float:
    """The panel's height in inches (0: no characteristics)."""
    cols, _ = panel_columns(panel_entries(result))
    if not cols:
        return 0.0
    return (TITLE + LINE * max(len(c) for c in cols) + 6.0) / 72.0


def _cut(fig, text, width_pt: float) -> None:
    """Cut ``text`` with "…" until its drawn width is at most ``width_pt`` points."""
    r = fig.canvas.get_renderer()
    to_pt = 72.0 / fig.dpi
    s = text.get_text()
    while text.get_window_extent(r).width * to_pt > width_pt and len(s) > 1:
        s = s[:-1]
        text.set_text(s.rstrip() + "…")


def _value(c, part):
    """The measured value (and verdict) a frame's line shows: a hole's part's own (its
    diameter's measured size, its position's zone value)."""
    from ..characteristics import registry
    from ..characteristics.evaluate import format_value

    m, verdict = c.measured, c.verdict
    if part is not None:
        m = m.get(part) if isinstance(m, dict) else None
        if not isinstance(m, (int, float)) and isinstance(c.deviation, dict):
            m = c.deviation.get(part)
        verdict = ((getattr(c, "details", None) or {}).get("verdicts") or {}).get(part, verdict)
    if isinstance(m, dict):
        m = None
    text = format_value(m)
    try:
        deg = registry.by_name(str(c.type)).unit == "deg"
    except KeyError:
        deg = False
    return (text + ("°" if deg and m is not None else "")), str(verdict)


def draw_panel(fig, result, x0: float, y_top: float, width: float) -> list:
    """Draw the panel with its top left corner at ``(x0, y_top)`` and ``width`` (inches from
    the figure's lower left); returns the texts it wrote."""
    cols, _ = panel_columns(panel_entries(result))
    if not cols:
        return []
    inch = fig.dpi_scale_trans
    k = 1.0 / 72.0
    texts = []

    def text(x_pt, y_pt, s, **kw):
        t = fig.text(x_pt * k, y_pt * k, font_text(s), transform=inch, va="center_baseline",
                     fontsize=kw.pop("fontsize", FONT), gid="characteristics", **kw)
        texts.append(t)
        return t

    left, top, w = x0 * 72.0, y_top * 72.0, width * 72.0
    n = len(getattr(result, "characteristics", ()) or ())
    t = text(left, top - TITLE / 2, f"Characteristics ({n}): feature control frames by datum "
             "reference frame; measured values in mm (° for angles), verdicts ISO 14253-1",
             fontsize=9.5, weight="bold")
    _cut(fig, t, w)
    cw = min(_MAX_COLUMN, (w - _GAP * (len(cols) - 1)) / len(cols))   # fields kept together
    nw, fw, vw = (f * cw for f in _FIELDS)
    for j, col in enumerate(cols):
        cx = left + j * (cw + _GAP)
        for i, e in enumerate(col):
            y = top - TITLE - LINE * (i + 0.5)
            if e[0] == "head":
                title = drf_title(e[1]) + (" (continued)" if e[2] else "")
                _cut(fig, text(cx, y, title, weight="bold", color="#333333"), cw)
            elif e[0] == "more":
                _cut(fig, text(cx, y, f"… and {e[1]} more: all in the HTML and PDF reports",
                               style="italic", color="#555555"), cw)
            else:
                _, c, f, idx = e
                if idx == 0:
                    _cut(fig, text(cx, y, str(c.name)), nw - 4.0)
                size, h = FONT, FRAME_H
                while size > MIN_FRAME_FONT and frame_width(fig, f, height=h,
                                                            fontsize=size) > fw - 4.0:
                    size, h = size - 0.5, h * (size - 0.5) / size
                # a frame still wider than its field takes room from the value's; one wider
                # than both is written as its text, cut
                room = cw - nw - 0.36 * vw - 4.0
                if frame_width(fig, f, height=h, fontsize=size) <= room:
                    used = draw_frame(fig, f, cx + nw, y - h / 2, height=h, fontsize=size,
                                      gid=f"png-fcf:{c.name}:{idx}")
                else:
                    t = text(cx + nw, y, f.text)
                    _cut(fig, t, room)
                    used = t.get_window_extent(fig.canvas.get_renderer()).width * 72 / fig.dpi
                xv = cx + nw + max(fw, used + 4.0)
                xd = cx + cw - 0.36 * vw
                val, verdict = _value(c, f.part)
                _cut(fig, text(xv, y, val, family="monospace"), xd - xv - 3.0)
                _cut(fig, text(xd, y, verdict, weight="bold",
                               color=_VERDICT_COLOURS.get(verdict, "#555555")), 0.36 * vw)
    return texts
