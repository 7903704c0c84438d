"""Composite feature control frames read from the STEP text (XCAF drops the
GEOMETRIC_TOLERANCE_RELATIONSHIP): NIST CTC 04's two composite frames, and the matching of
segments to the tolerances XCAF reads."""
import gzip
from pathlib import Path

import pytest

from shapeverify.cad.step_composite import composite_relations_of_text, match_composites

CTC04 = Path(__file__).parent / "data" / "nist_extra" / "nist_ctc_04_asme1_ap242-e1.stp.gz"


@pytest.fixture(scope="module")
def ctc04_text():
    return gzip.open(CTC04, "rt", encoding="latin-1").read()


def test_ctc04_composite_frames_are_read_from_the_step_text(ctc04_text):
    rels = composite_relations_of_text(ctc04_text)
    got = [(r["upper"]["entity"], r["upper"]["type"], r["upper"]["value"],
            r["upper"]["n_datums"], r["lower"]["entity"], r["lower"]["value"],
            r["lower"]["n_datums"]) for r in rels]
    # the file's text: #18733 relates #18715 (1.5, D|E|F) to #18730 (0.3, D|E); #18794
    # relates #18781 (profile 2, D|G|H) to #18793 (0.2, D)
    assert got == [(18715, "Position", 1.5, 3, 18730, 0.3, 2),
                   (18781, "ProfileOfSurface", 2.0, 3, 18793, 0.2, 1)]
    assert ctc04_text.count("GEOMETRIC_TOLERANCE_RELATIONSHIP(") == 2


def _tol(i, t, v, datums, faces):
    return {"id": f"GT{i}", "type": t, "value": v,
            "datums": [{"name": d, "order": k + 1} for k, d in enumerate(datums)],
            "faces": faces}


def test_composite_segments_matched_by_type_value_datums_and_faces(ctc04_text):
    rels = composite_relations_of_text(ctc04_text)
    tols = [_tol(1, "Position", 0.3, "ABC", [27, 28]),      # same value, other faces
            _tol(2, "Position", 1.5, "DEF", [1, 2]),
            _tol(3, "Position", 0.3, "DE", [2, 1]),
            _tol(4, "ProfileOfSurface", 2.0, "DGH", [307, 308]),
            _tol(5, "ProfileOfSurface", 0.2, "D", [307, 308]),
            _tol(6, "ProfileOfSurface", 0.2, "D", [400])]
    assert match_composites(rels, tols) == []
    marks = {t["id"]: (t["composite"]["segment"], t["composite"]["with"])
             for t in tols if "composite" in t}
    assert marks == {"GT2": ("upper", "GT3"), "GT3": ("lower", "GT2"),
                     "GT4": ("upper", "GT5"), "GT5": ("lower", "GT4")}


def test_composite_segments_in_inch_files_are_matched_through_the_unit(ctc04_text):
    rels = composite_relations_of_text(ctc04_text)[:1]
    tols = [_tol(2, "Position", 1.5 * 25.4, "DEF", [1]), _tol(3, "Position", 0.3 * 25.4,
                                                              "DE", [1])]
    assert match_composites(rels, [dict(t) for t in tols])[0]["reason"].startswith("0 pairs")
    assert match_composites(rels, tols, 25.4) == []
    assert tols[1]["composite"]["segment"] == "lower"


def test_ambiguous_composite_segments_are_left_unmarked(ctc04_text):
    rels = composite_relations_of_text(ctc04_text)[:1]
    tols = [_tol(2, "Position", 1.5, "DEF", [1]), _tol(3, "Position", 0.3, "DE", [1]),
            _tol(7, "Position", 1.5, "DEF", [1])]
    missed = match_composites(rels, tols)
    assert len(missed) == 1 and not any("composite" in t for t in tols)


@pytest.mark.slow
def test_ctc04_plan_marks_the_lower_segments_of_its_composite_frames(tmp_path):
    """CTC 04 (PMI read ~100 s): GT2/GT3 (position 1.5 D|E|F over 0.3 D|E of six holes) and
    GT4/GT5 (profile 2 D|G|H over 0.2 D of faces 307, 308) are planned as upper and lower
    segments, each lower one in its own DRF (not the plan's alignment, not per hole)."""
    import shutil

    from nist_plans import cached_pmi_plan

    p = tmp_path / "nist_ctc_04_asme1_ap242-e1.stp"
    with gzip.open(CTC04, "rb") as src, open(p, "wb") as dst:
        shutil.copyfileobj(src, dst)
    # pmi_plan(p), with its import, PMI and features shared with test_nist_extra_plans.py
    res = cached_pmi_plan(p)
    by = {}
    for c in res.data["characteristics"]:
        by.setdefault(c["pmi"].get("id"), []).append(c)
    got = {k: [(c["type"], c.get("composite"), tuple(c.get("datums") or ()), c["tol"])
               for c in by[k]] for k in ("GT2", "GT3", "GT4", "GT5")}
    assert got == {"GT2": [("position", "upper", ("D", "E", "F"), 1.5)],
                   "GT3": [("position", "lower", ("D", "E"), 0.3)],
                   "GT4": [("surface_profile", "upper", ("D", "G", "H"), 2.0)],
                   "GT5": [("surface_profile", "lower", ("D",), 0.2)]}
    assert len(by["GT3"][0]["features"]) == 6
    assert by["GT3"][0]["pmi"]["composite"] == {"segment": "lower", "with": "GT2",
                                                "entity": "#18730"}
    assert "composites_unmatched" not in res.pmi


def test_ftc07_composite_frames_are_matched_in_inches(tmp_path):
    """NIST FTC 07 declares the millimetre before its inch (the inch's base unit): the file's
    unit was read as mm, no composite segment's value matched (0.06 in against 1.524 mm), and its
    six composite frames were planned as separately located tolerances."""
    from shapeverify.cad.pmi import read_pmi
    from shapeverify.cad.step_units import length_unit_of_file

    path = tmp_path / "ftc07.stp"
    path.write_bytes(gzip.open(CTC04.parent / "nist_ftc_07_asme1_ap242-e2.stp.gz").read())
    assert length_unit_of_file(path) == ("INCH", 25.4)
    pmi = read_pmi(path)
    assert "composites_unmatched" not in pmi
    marks = {}
    for t in pmi["tolerances"]:
        if t.get("composite"):
            marks.setdefault(t["name"], []).append(t["composite"]["segment"])
    assert {n: sorted(s) for n, s in marks.items()} == {
        n: ["lower", "upper"] for n in ("GP7", "GP12", "GP13", "GP15", "GP16", "GP19")}
