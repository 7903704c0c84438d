"""Feature control frames in the reports and SPC (issue 28 item 4): each characteristic as the
drawing writes it (symbol, zone, modifiers, datums), the reports grouped by datum reference
frame, and history / Cp/Cpk / CSV for every registered characteristic type.

The NIST plans in ``tests/data/pmi_plans`` are ``shapeverify plan`` outputs of the NIST AP242
files (``nist_*_asme1_ap242-e1.stp``, FTC 06, FTC 08, CTC 02) so that the fast tests need no
CAD reading (a minute a file); ``test_plan_read_from_the_step_file_renders_every_frame`` reads
one afresh (slow).
"""
from __future__ import annotations

import csv
import dataclasses
import sqlite3
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from fcf_synthetic import synthetic_plan_result, synthetic_result
from shapeverify.characteristics import registry
from shapeverify.characteristics.plan import load_plan
from shapeverify.report import fcf as F

PLANS = Path(__file__).parent / "data" / "pmi_plans"
NIST = ["nist_ftc_06", "nist_ftc_08", "nist_ctc_02"]


# ------------------------------------------------------------------ the symbol column, row by row
#: type -> (a plan entry of it, the frame the drawing writes); one per registry row
ROWS = {
    "hole": ({"type": "hole", "feature": "hole:1", "diameter": {"lower": -0.05, "upper": 0.05},
              "position": {"tol": 0.5}, "pmi": {"kind": "geometric_tolerance",
                                                "type": "Position", "datums": "A|B|C"}},
             "Ø10.000 +0.05/−0.05; ⌖|Ø0.5|A|B|C"),
    "surface_profile": ({"type": "surface_profile", "tol": 0.2, "datums": ["A", "B"]},
                        "⌓|0.2|A|B"),
    "flatness": ({"type": "flatness", "tol": 0.05, "feature": "face:1"}, "⏥|0.05"),
    "cylinder": ({"type": "cylinder", "feature": "face:2", "diameter": {"tol": 0.05}},
                 "Ø25.000 +0.05/−0.05"),
    "check_point": ({"type": "check_point", "tol": 0.1, "at": [0, 0, 0]}, "+0.1/−0.1"),
    "straightness": ({"type": "straightness", "faces": ["face:2"], "tol": 0.02,
                      "zone": "diameter"}, "⏤|Ø0.02"),
    "circularity": ({"type": "circularity", "faces": ["face:2"], "tol": 0.01}, "○|0.01"),
    "cylindricity": ({"type": "cylindricity", "faces": ["face:2"], "tol": 0.03}, "⌭|0.03"),
    "parallelism": ({"type": "parallelism", "faces": ["face:3"], "tol": 0.1, "datums": ["A"],
                     "tangent_plane": True}, "∥|0.1Ⓣ|A"),
    "perpendicularity": ({"type": "perpendicularity", "faces": ["face:2"], "tol": 0.1,
                          "datums": ["A"], "zone": "diameter", "material": "M",
                          "size": {"lower": -0.1, "upper": 0.1}}, "⊥|Ø0.1Ⓜ|A"),
    "angularity": ({"type": "angularity", "faces": ["face:4"], "tol": 0.2,
                    "datums": ["A", "B"]}, "∠|0.2|A|B"),
    "position": ({"type": "position", "features": ["hole:1"], "tol": 0.25, "datums":
                  ["A", "B", "C"], "material": "L", "size": {"lower": -0.1, "upper": 0.1}},
                 "⌖|Ø0.25Ⓛ|A|B|C"),
    "circular_runout": ({"type": "circular_runout", "faces": ["face:2"], "tol": 0.05,
                         "datums": ["A"]}, "↗|0.05|A"),
    "total_runout": ({"type": "total_runout", "faces": ["face:2"], "tol": 0.08,
                      "datums": ["A", "B"]}, "⌰|0.08|A|B"),
    "concentricity": ({"type": "concentricity", "faces": ["face:2"], "tol": 0.762,
                       "datums": ["A"]}, "◎|Ø0.762|A"),
    "symmetry": ({"type": "symmetry", "faces": ["face:5", "face:6"], "tol": 0.5,
                  "datums": ["A", "B"]}, "⌯|0.5|A|B"),
    "width": ({"type": "width", "faces": ["face:5", "face:6"], "lower": -0.1, "upper": 0.2},
              "25.000 +0.2/−0.1"),
    "distance": ({"type": "distance", "faces": ["face:5", "face:6"], "nominal": 25.0,
                  "lower": -0.1, "upper": 0.2}, "25.000 +0.2/−0.1"),
    "angle": ({"type": "angle", "faces": ["face:4", "face:5"], "nominal": 60.0, "lower": -0.5,
               "upper": 0.5}, "60.000° +0.5°/−0.5°"),
    "line_profile": ({"type": "line_profile", "faces": ["face:3"], "tol": 0.25,
                      "normal": [1.0, 0.0, 0.0], "datums": ["A", "B", "C"]}, "⌒|0.25|A|B|C"),
    "position_zone": ({"type": "position_zone", "faces": ["face:3", "face:4"], "tol": 0.635,
                       "zone": "sphere", "datums": ["A", "B"]}, "⌖|SØ0.635|A|B"),
    "feature_size": ({"type": "feature_size", "faces": ["face:3"], "shape": "sphere",
                      "size": "radius", "lower": -0.508, "upper": 0.508, "nominal": 12.7},
                     "SR12.700 +0.508/−0.508"),
    "cone_angle": ({"type": "cone_angle", "faces": ["face:3", "face:4"], "angle": "included",
                    "nominal": 90.0, "lower": -1.0, "upper": 1.0}, "90.000° +1°/−1°"),
    "cone_diameter": ({"type": "cone_diameter", "faces": ["face:3", "face:4"],
                       "at": ["face:1"], "nominal": 20.0, "lower": -0.3, "upper": 0.3},
                      "Ø20.000 +0.3/−0.3"),
}
DATUMS = {k: {"faces": ["face:1"]} for k in "ABC"}


def _entry(t):
    """The validated plan entry of type ``t`` (the plan's own schema)."""
    plan = load_plan({"datums": DATUMS, "characteristics": [{"name": f"X_{t}", **ROWS[t][0]}]})
    return plan.characteristics[0]


def test_every_registered_type_has_a_row_here():
    """A new registry row must come with its frame pinned in ROWS (and so in every test)."""
    assert sorted(ROWS) == sorted(t.name for t in registry.TYPES), \
        "add a plan entry and its expected frame to ROWS for the new characteristic type"


@pytest.mark.parametrize("t", sorted(ROWS))
def test_symbol_row_gives_the_frame_the_drawing_writes(t):
    entry = _entry(t)
    res = synthetic_result(entry)
    assert F.fcf_text(res, entry) == ROWS[t][1]
    sym = registry.by_name(t).symbol
    if sym in F.SYMBOLS:                     # a tolerance: framed, symbol drawn without a font
        assert F.frames(res, entry)[-1].is_tolerance
        assert F.drawn_symbol(sym) == ("strokes", sym)
        assert f'aria-label="{sym} ' in F.svg_symbol(sym)


def test_new_registry_row_just_works(monkeypatch):
    """A type another change adds (profile of a line) frames from its row alone."""
    row = registry.CharacteristicType("line_profile", object, "gdt:none", True,
                                      "profile of a line", "⌒")
    monkeypatch.setitem(registry._BY_NAME, "line_profile", row)
    entry = {"type": "line_profile", "tol": 0.1, "datums": ["A", "B"]}
    assert F.fcf_text({"type": "line_profile", "upper": 0.1}, entry) == "⌒|0.1|A|B"
    assert F.fcf_text({"type": "line_profile", "upper": 0.1}) == "⌒|0.1"   # no plan entry
    dist = registry.CharacteristicType("distance", object, "gdt:none", False, "distance")
    monkeypatch.setitem(registry._BY_NAME, "distance", dist)
    assert F.fcf_text({"type": "distance", "nominal": 40.0, "lower": -0.1,
                       "upper": 0.1}) == "40.000 +0.1/−0.1"


def test_registry_row_without_its_symbol_takes_the_pmis_or_its_label(monkeypatch):
    """A row added without the symbol column (its default "") is still framed: with the PMI
    type's symbol, else (a zone width) with its label in the symbol's place."""
    row = registry.CharacteristicType("line_profile", object, "gdt:none", True,
                                      "profile of a line")
    monkeypatch.setattr(registry, "TYPES", registry.TYPES + (row,))
    monkeypatch.setitem(registry._BY_NAME, "line_profile", row)
    pmi = {"kind": "geometric_tolerance", "type": "ProfileOfLine", "datums": "A"}
    res = {"type": "line_profile", "upper": 0.1}
    assert F.fcf_text(res, {"type": "line_profile", "tol": 0.1, "pmi": pmi}) == "⌒|0.1|A"
    f, = F.frames(res, {"type": "line_profile", "tol": 0.1})
    assert f.is_tolerance and f.text == "profile of a line|0.1"
    assert F.drawn_symbol("profile of a line") == ("text", "profile of a line")


def test_sizes_are_written_as_dimensions_with_their_limits():
    cyl = {"type": "cylinder", "nominal": 20.0, "lower": -0.05, "upper": 0.05}
    assert F.fcf_text(cyl) == "Ø20.000 +0.05/−0.05"
    assert F.fcf_text({**cyl, "lower": 0.0, "upper": 0.2}) == "Ø20.000 +0.2/0"
    assert F.fcf_text({**cyl, "nominal": 5.4102}) == "Ø5.4102 +0.05/−0.05"
    # the drawing's nominal (the PMI's), not the CAD's measured one
    entry = {"type": "cylinder", "diameter": {"lower": -0.0254, "upper": 0.127},
             "pmi": {"kind": "dimension", "type": "Size_Diameter", "nominal": 6.35}}
    res = {**cyl, "nominal": 6.3499, "lower": -0.0254, "upper": 0.127}
    assert F.fcf_text(res, entry) == "Ø6.350 +0.127/−0.0254"


def test_modifiers_zone_modifiers_and_datum_modifiers_in_their_compartments():
    pmi = {"kind": "geometric_tolerance", "type": "Position", "datums": "A|B|C",
           "zone": "Diameter", "material": "M", "modifiers": ["Free_State", "Common_Zone",
                                                              "All_Around", "Odd_New_One"],
           "zone_modifier": "Projected", "zone_modifier_value": 12.0,
           "datum_modifiers": {"B": ["MaximumMaterialRequirement"], "C": ["FreeState"]}}
    f, = F.frames({"type": "position", "upper": 0.4}, {"type": "position", "tol": 0.3,
                                                       "pmi": pmi})
    assert f.text == "⌖|Ø0.3Ⓟ12ⓂⒻCZ[Odd_New_One]|A|BⓂ|CⒻ (all around)"
    assert f.datums == ("A", "B", "C") and f.notes == ("all around",)
    # the zone is the drawing's 0.3, not the result's bonus-enlarged 0.4
    assert f.compartments[1][:2] == (("text", "Ø"), ("text", "0.3"))
    # a profile with unequal limits: Ⓤ and the part outside the material
    prof = {"type": "surface_profile", "lower": -0.1, "upper": 0.3}
    assert F.fcf_text({"type": "surface_profile"}, prof) == "⌓|0.4Ⓤ0.3"
    # free state and tangent plane from the PMI and the entry, each once (NIST FTC 08 GT8)
    par = {"type": "parallelism", "tol": 0.762, "datums": ["A"], "tangent_plane": True,
           "pmi": {"kind": "geometric_tolerance", "type": "Parallelism",
                   "modifiers": ["Free_State", "Tangent_Plane"]}}
    assert F.fcf_text({"type": "parallelism"}, par) == "∥|0.762ⒻⓉ|A"


def test_font_lacks_most_symbols_so_the_drawn_forms_do_not_use_it():
    """DejaVu Sans (matplotlib's) has neither ⌖ nor Ⓜ: the frames draw them as strokes and
    circles; the text fallback uses the standard's abbreviations."""
    assert not F._font_has("⌖") and not F._font_has("Ⓜ") and F._font_has("⊥")
    assert all(sym in F.STROKES for sym in F.SYMBOLS)
    assert F.font_text("⌖|Ø0.5Ⓜ|A") == "POS|Ø0.5(M)|A"


# ------------------------------------------------------------------ the PDF: frames drawn, grouped
def _table_figures(pr):
    from shapeverify.characteristics.pdf import _pages_table

    figs = _pages_table(pr, "NIST")
    for fig in figs:
        fig.canvas.draw()
    return figs


def _expected_groups(pr):
    entries = {c.name: c for c in pr.plan.characteristics}
    items = [(c.name, F.frames(c, entries[c.name])) for c in pr.characteristics]
    return items, F.group_by_drf(items)


@pytest.mark.slow
@pytest.mark.parametrize("name", NIST)
def test_pdf_table_draws_every_frame_in_its_cell_grouped_by_drf(name):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon, Rectangle
    from matplotlib.text import Text

    pr = synthetic_plan_result(PLANS / f"{name}.yaml")
    items, groups = _expected_groups(pr)
    figs = _table_figures(pr)
    # the headings and rows top to bottom, page by page
    order = []
    for fig in figs:
        r = fig.canvas.get_renderer()
        marks = []
        for t in fig.findobj(Text):
            gid = t.get_gid() or ""
            if gid == "drf-heading":
                marks.append((-t.get_window_extent(r).y0, "head", t.get_text()))
        rows = {}
        for a in fig.findobj(lambda a: (a.get_gid() or "").startswith("fcf:")):
            head, i = a.get_gid().rsplit(":", 1)          # "fcf:NAME:i"
            rows.setdefault((head[4:], int(i)), []).append(a)
        for (cname, i), arts in rows.items():
            y = min(-a.get_window_extent(r).y0 for a in arts)
            if i == 0:
                marks.append((y, "row", cname))
            # the frame: its texts, left to right, are its text tokens; its symbol's strokes
            f = dict(items)[cname][i]
            texts = sorted((a for a in arts if isinstance(a, Text)),
                           key=lambda a: a.get_window_extent(r).x0)
            want = [v for c in f.compartments for k, v in c if k in ("text", "circled")]
            got = [a.get_text() for a in texts]
            assert got[:len(want)] == [F.font_text(v) for v in want], (cname, got, want)
            strokes = [a for a in arts if isinstance(a, (Line2D, Polygon))]
            n_sym = len(F.STROKES.get(f.symbol, ())) if f.is_tolerance else 0
            assert len(strokes) == n_sym
            boxes = [a for a in arts if isinstance(a, Rectangle)]
            assert len(boxes) == (len(f.compartments) if f.is_tolerance else 0)
        order += [m[1:] for m in sorted(marks)]
    # every characteristic once, under its DRF's heading, the groups in order
    want = []
    for drf, group in groups:
        want.append(("head", F.drf_title(drf)))
        want += [("row", n) for n, _ in group]
    got = [o for o in order if not (o[0] == "head" and o[1].endswith("(continued)"))]
    assert got == want
    assert sum(o[0] == "row" for o in got) == len(pr.characteristics)


@pytest.mark.slow  # 3.0 s of CPU with numba's cache warm (quick tests: under ~3 s)
def test_pdf_frames_lie_inside_their_cells_and_a4():
    """The widest frames of FTC 08 (⌖ Ø0.5842 Ⓜ Ⓕ A B C) fit the frame column."""
    from matplotlib.table import Table

    pr = synthetic_plan_result(PLANS / "nist_ftc_08.yaml")
    for fig in _table_figures(pr):
        r = fig.canvas.get_renderer()
        tab = next(a for a in fig.findobj(Table))
        col = [c for (i, j), c in tab.get_celld().items() if j == 1 and i > 0]
        x0 = min(c.get_window_extent(r).x0 for c in col)
        x1 = max(c.get_window_extent(r).x1 for c in col)
        arts = fig.findobj(lambda a: (a.get_gid() or "").startswith("fcf:"))
        assert arts
        assert not fig.findobj(lambda a: a.get_gid() == "_measure")   # measured, then removed
        for a in arts:
            bb = a.get_window_extent(r)
            assert x0 - 0.5 <= bb.x0 and bb.x1 <= x1 + 0.5, a.get_gid()
            assert 0 <= bb.y0 and bb.y1 <= fig.bbox.height


def test_pdf_and_run_chart_need_no_glyph_the_font_lacks(tmp_path):
    """Ⓛ ⌖ ⌓ are not in DejaVu Sans: written, the PDF and the run chart (its title carries the
    frame) must not ask the font for them (matplotlib warns "Glyph ... missing")."""
    import warnings

    from shapeverify.characteristics.pdf import ReportLabels, write_pdf_report
    from shapeverify.characteristics.spc import plot_run_chart

    pr = synthetic_plan_result(PLANS / "nist_ctc_02.yaml")
    pos = next(c for c in pr.characteristics if c.type == "position")
    rows = [{"id": i, "part": f"P{i}", "name": pos.name, "value": 0.05 + 0.01 * (i % 3),
             "lower": None, "upper": 0.15, "verdict": "pass",
             "fcf": F.fcf_text(pos, pr.plan.characteristics[pr.characteristics.index(pos)])}
            for i in range(5)]
    assert "Ⓛ" in rows[0]["fcf"] and "⌖" in rows[0]["fcf"]
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*missing from font.*")
        out = write_pdf_report(pr, tmp_path / "r.pdf", max_points=200,
                               labels=ReportLabels(part="CTC 02", date="2026-12-06"))
        plot_run_chart(rows, tmp_path / "run.png")
    data = out.read_bytes()
    assert data.startswith(b"%PDF") and len(data) > 20_000


# ------------------------------------------------------------------ the HTML report
class _Rows(HTMLParser):
    """The characteristics table's rows: ("head", data-drf) and ("row", name, [data-fcf])."""

    def __init__(self):
        super().__init__()
        self.rows, self._in = [], False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._in = "chars" in (a.get("class") or "").split()
        if not self._in:
            return
        if tag == "tr" and a.get("class") == "drf":
            self.rows.append(("head", a.get("data-drf")))
        elif tag == "tr" and "data-name" in a:
            self.rows.append(("row", a["data-name"], []))
        elif "data-fcf" in a:
            self.rows[-1][2].append(a["data-fcf"])

    def handle_endtag(self, tag):
        if tag == "table":
            self._in = False


@pytest.mark.parametrize("name", ["nist_ftc_06", "nist_ctc_02"])
def test_html_table_shows_every_frame_grouped_by_drf(name):
    pytest.importorskip("plotly")
    from shapeverify.report.html import render_html
    from test_report_layout import _inspected

    res, _ = _inspected(100.0, "NIST", dent=False)
    pr = synthetic_plan_result(PLANS / f"{name}.yaml")
    res = dataclasses.replace(res, plan=pr, characteristics=pr.characteristics)
    page = render_html(res, None, max_points=500)
    p = _Rows()
    p.feed(page)
    items, groups = _expected_groups(pr)
    want = []
    for drf, group in groups:
        want.append(("head", "|".join(drf)))
        want += [("row", n, [f.text for f in fs]) for n, fs in group]
    assert p.rows == want
    assert 'class="fcf-sym" role="img"' in page and "@page{size:A4 portrait" in page


# ------------------------------------------------------------------ history, Cp/Cpk, CSV
def test_history_capability_and_csv_take_every_registered_type(tmp_path):
    from types import SimpleNamespace

    from shapeverify.characteristics.spc import (capability, characteristic_names,
                                                 characteristic_rows, export_csv,
                                                 store_characteristics)

    plan = load_plan({"datums": DATUMS, "characteristics": [
        {"name": f"X_{t.name}", **ROWS[t.name][0]} for t in registry.TYPES]})
    db = tmp_path / "h.sqlite"
    rng = np.random.default_rng(1)
    fractions = rng.uniform(0.2, 0.6, 30)
    for i, fr in enumerate(fractions):
        chars = tuple(synthetic_result(c, fr) for c in plan.characteristics)
        store_characteristics(db, SimpleNamespace(characteristics=chars, plan=plan),
                              part=f"P{i:02d}", time=f"2026-12-01T10:{i:02d}:00")
    names = characteristic_names(db)
    for c in plan.characteristics:
        res = synthetic_result(c, 0.5)
        series = ([f"{c.name}.{k}" for k in res.upper] if isinstance(res.upper, dict)
                  else [c.name])
        for s in series:
            assert s in names
            rows = characteristic_rows(db, s)
            assert len(rows) == 30
            part = s.split(".")[1] if "." in s else None
            assert {r["fcf"] for r in rows} == {F.fcf_text(res, c, part)}
            y = np.array([r["value"] for r in rows])
            lo, hi = rows[-1]["lower"], rows[-1]["upper"]
            cap = capability(y, lo, hi)
            sw = np.mean(np.abs(np.diff(y))) / 1.128
            if lo is None:                                   # a zone width: one-sided
                assert cap.cp is None and cap.cpk == pytest.approx((hi - y.mean()) / (3 * sw))
            else:
                assert cap.cp == pytest.approx((hi - lo) / (6 * sw))
            out = export_csv(rows, tmp_path / "s.csv")
            with open(out, newline="", encoding="utf-8") as fh:
                back = list(csv.DictReader(fh))
            assert len(back) == 30 and back[0]["fcf"] == F.fcf_text(res, c, part)
            np.testing.assert_allclose([float(b["value"]) for b in back], y)


def test_history_written_before_the_frames_gets_the_column(tmp_path):
    from types import SimpleNamespace

    from shapeverify.characteristics.evaluate import CharacteristicResult
    from shapeverify.characteristics.spc import characteristic_rows, store_characteristics

    db = tmp_path / "old.sqlite"
    con = sqlite3.connect(db)
    con.executescript("""CREATE TABLE characteristics (id INTEGER PRIMARY KEY AUTOINCREMENT,
        inspection_id INTEGER, part TEXT, time TEXT NOT NULL, name TEXT NOT NULL,
        type TEXT NOT NULL, nominal REAL, measured REAL, value REAL, lower REAL, upper REAL,
        uncertainty REAL, verdict TEXT NOT NULL);
        INSERT INTO characteristics (part, time, name, type, value, upper, verdict)
        VALUES ('old', '2026-01-01', 'F', 'flatness', 0.01, 0.05, 'pass');""")
    con.commit()
    con.close()
    new = CharacteristicResult("F", "flatness", 0.0, 0.02, 0.02, 0.0, 0.05, 0.002, "pass")
    store_characteristics(db, SimpleNamespace(characteristics=(new,),
                                              plan=SimpleNamespace(part="new")))
    rows = characteristic_rows(db, "F")
    assert [r["fcf"] for r in rows] == [None, "⏥|0.05"]
    assert [r["value"] for r in rows] == [0.01, 0.02]


# ------------------------------------------------------------------ from the STEP file (slow)
@pytest.mark.slow
def test_plan_read_from_the_step_file_renders_every_frame(shared_data, monkeypatch):
    """``plan_from_pmi`` of NIST FTC 08 afresh: every characteristic's frame in the PDF table,
    each tolerance with the PMI's own datums."""
    from model_cache import load_model_stand_in, read_pmi_stand_in

    import shapeverify.cad.load
    import shapeverify.cad.pmi
    from shapeverify.characteristics import plan_from_pmi

    # its import and PMI from the suite's cache (tests/model_cache.py: bitwise what load_model
    # and read_pmi give; the NIST modules read the same file); the plan is made afresh
    monkeypatch.setattr(shapeverify.cad.load, "load_model", load_model_stand_in)
    monkeypatch.setattr(shapeverify.cad.pmi, "read_pmi", read_pmi_stand_in)
    step = shared_data / "cad" / "nist" / "nist_ftc_08_asme1_ap242-e1.stp"
    plan = plan_from_pmi(step)
    pr = synthetic_plan_result(plan)
    figs = _table_figures(pr)
    drawn = {a.get_gid().rsplit(":", 1)[0][4:] for fig in figs
             for a in fig.findobj(lambda a: (a.get_gid() or "").startswith("fcf:"))}
    assert drawn == {c.name for c in plan.characteristics}
    for c in plan.characteristics:
        fs = F.frames(synthetic_result(c), c)
        if c.pmi is not None and c.pmi.kind == "geometric_tolerance":
            pmi_drf = tuple((c.pmi.model_dump().get("datums") or "").split("|")) \
                if c.pmi.model_dump().get("datums") else ()
            assert F.drf_key(fs) == _join_common(pmi_drf, plan.datums)


def _join_common(names, table):
    """The PMI's datum letters with a common datum's letters joined as the plan's table names
    it (``D|E|F`` with a table entry ``E-F``: ``('D', 'E-F')``)."""
    out, i = [], 0
    while i < len(names):
        for j in range(len(names), i + 1, -1):
            if "-".join(names[i:j]) in table:
                out.append("-".join(names[i:j]))
                i = j
                break
        else:
            out.append(names[i])
            i += 1
    return tuple(out)


def test_a_characteristic_not_measured_still_shows_the_drawings_frame():
    """No values (too few scan points): the frames come from the plan entry alone."""
    from shapeverify.characteristics.evaluate import CharacteristicResult

    def unmeasured(entry):
        return CharacteristicResult(entry.name, entry.type, None, None, None, None, None, None,
                                    "undecided", {"reason": "no scan points"})

    hole = _entry("hole")
    assert F.fcf_text(unmeasured(hole), hole) == "Ø +0.05/−0.05; ⌖|Ø0.5|A|B|C"
    pos = _entry("position")
    assert F.fcf_text(unmeasured(pos), pos) == "⌖|Ø0.25Ⓛ|A|B|C"
    width = _entry("width")
    assert F.fcf_text(unmeasured(width), width) == "+0.2/−0.1"
    cyl = _entry("cylinder")
    assert F.fcf_text(unmeasured(cyl), cyl) == "Ø +0.05/−0.05"


def test_history_characteristic_table_shows_the_feature_control_frame(tmp_path):
    """``history --characteristic`` prints the series' latest frame (issue 28 item 4)."""
    from types import SimpleNamespace

    from typer.testing import CliRunner

    from shapeverify.characteristics.spc import store_characteristics
    from shapeverify.cli import app

    plan = load_plan({"datums": DATUMS, "characteristics": [
        {"name": "LP", **ROWS["line_profile"][0]}]})
    db = tmp_path / "h.sqlite"
    for i, fr in enumerate((0.2, 0.4, 0.3)):
        chars = tuple(synthetic_result(c, fr) for c in plan.characteristics)
        store_characteristics(db, SimpleNamespace(characteristics=chars, plan=plan),
                              part=f"P{i}", time=f"2026-12-01T10:0{i}:00")
    r = CliRunner().invoke(app, ["history", "--db", str(db), "--characteristic", "LP"],
                           env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    assert ROWS["line_profile"][1] in r.output
