"""The run chart's legend (issue 32 item 4): "the run chart's ``undecided`` point has no legend
entry" -- its points were coloured by verdict (blue, red, orange) with no legend at all.  Each
panel's legend now names the colour of every verdict its points show, the mean and control
limits, and the specification limits."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgba

from shapeverify.characteristics.spc import run_chart_figure


def _rows(verdicts, name="SKIN", upper=0.2):
    return [{"id": i + 1, "part": f"P{i + 1}", "name": name, "value": 0.1 + 0.02 * (i % 5),
             "lower": None, "upper": upper, "verdict": v} for i, v in enumerate(verdicts)]


def _legend(ax):
    leg = ax.get_legend()
    assert leg is not None, "the panel has no legend"
    return {t.get_text(): h for t, h in zip(leg.get_texts(), leg.legend_handles)}


def test_run_chart_legend_names_the_undecided_points_colour():
    verdicts = ["pass"] * 6 + ["undecided"] + ["pass"] * 3 + ["fail"] + ["pass"] * 2
    fig = run_chart_figure(_rows(verdicts))
    ax = fig.axes[0]
    entries = _legend(ax)
    assert {"pass", "fail", "undecided", "mean", "control limits",
            "specification limits"} <= set(entries)
    # each verdict's entry has the colour its points are drawn in (read from the drawn points)
    pts = ax.collections[0]
    xy, face = pts.get_offsets(), pts.get_facecolors()
    for v in ("pass", "fail", "undecided"):
        i = verdicts.index(v)
        assert xy[i][0] == i + 1
        assert np.allclose(to_rgba(entries[v].get_markerfacecolor()), face[i]), v
    fig.canvas.draw()          # the legend fits in its panel
    r = fig.canvas.get_renderer()
    box, frame = ax.get_legend().get_window_extent(r), ax.bbox
    assert frame.x0 - 0.5 <= box.x0 and box.x1 <= frame.x1 + 0.5
    assert frame.y0 - 0.5 <= box.y0 and box.y1 <= frame.y1 + 0.5


def test_run_chart_legend_lists_only_the_verdicts_drawn():
    fig = run_chart_figure(_rows(["pass"] * 4, name="A") + _rows(["pass", "undecided"], name="B"))
    a, b = fig.axes
    assert "undecided" not in _legend(a) and "fail" not in _legend(a)
    assert {"pass", "undecided"} <= set(_legend(b)) and "fail" not in _legend(b)
