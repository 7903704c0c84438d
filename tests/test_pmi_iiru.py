"""Datums that a STEP file ties to faces by an ITEM_IDENTIFIED_REPRESENTATION_USAGE whose item
OpenCASCADE's XCAF reader does not read (NIST CTC 01's datums B and C:
``SET_REPRESENTATION_ITEM((#854,#853))``), resolved by :mod:`shapeverify.cad.pmi_iiru`.

The faces are checked against an independent reading of the STEP text (a regex walk, not the
module's parser): the IIRU's ADVANCED_FACE entities, their CYLINDRICAL_SURFACE (axis point,
direction, radius); every vertex of every face the read attaches the datum to must lie on that
cylinder, and the two datums' cylinders must differ.
"""
from __future__ import annotations

import re
from collections import Counter

import numpy as np
import pytest

CTC01 = ("cad", "nist", "nist_ctc_01_asme1_ap242-e1.stp")


def _entities(path) -> dict:
    text = path.read_text(encoding="latin-1")
    body = text[text.index("DATA;"):]
    return {int(m.group(1)): " ".join(m.group(2).split())
            for m in re.finditer(r"#(\d+)\s*=\s*(.*?);\s*(?=#\d+\s*=|ENDSEC)", body, re.S)}


def _nums(s: str) -> list[float]:
    return [float(x) for x in re.findall(r"[-+]?\d+\.?\d*(?:[Ee][-+]?\d+)?", s)]


def _cylinders_of_datums(path) -> dict:
    """{datum letter: [(point, direction, radius) of each IIRU face]} from the STEP text."""
    ents = _entities(path)
    refs = lambda s: [int(x) for x in re.findall(r"#(\d+)", s)]  # noqa: E731
    letter = {}
    for k, v in ents.items():                 # SHAPE_ASPECT_RELATIONSHIP(.., feature, datum)
        if v.startswith("SHAPE_ASPECT_RELATIONSHIP("):
            a, b = refs(v)[-2:]
            m = re.match(r"DATUM\(.*'(\w+)'\)$", ents[b])
            if m:
                letter[a] = m.group(1)
    out = {}
    for k, v in ents.items():
        if not v.startswith("ITEM_IDENTIFIED_REPRESENTATION_USAGE(") or \
                "SET_REPRESENTATION_ITEM" not in v:
            continue
        r = refs(v)
        name = letter[r[0]]
        cyl = []
        for f in refs(v[v.index("SET_REPRESENTATION_ITEM"):]):
            assert ents[f].startswith("ADVANCED_FACE("), ents[f]
            surf = ents[refs(ents[f])[-1]]
            assert surf.startswith("CYLINDRICAL_SURFACE("), surf
            ax = ents[refs(surf)[0]]
            p, d = refs(ax)[:2]
            cyl.append((np.array(_nums(ents[p].split(",", 1)[1])),
                        np.array(_nums(ents[d].split(",", 1)[1])),
                        _nums(surf.rsplit(",", 1)[1])[0]))
        out[name] = cyl
    return out


@pytest.fixture(scope="module")
def ctc01_pmi(shared_data):
    from model_cache import cached_pmi

    path = shared_data.joinpath(*CTC01)
    if not path.exists():
        pytest.skip(f"{path} not present (NIST MBE PMI test model)")
    return path, cached_pmi(path)       # read_pmi's, once per suite run (tests/model_cache.py)


def test_ctc01_datums_b_and_c_are_attached_to_the_faces_their_iiru_names(ctc01_pmi):
    path, pmi = ctc01_pmi
    truth = _cylinders_of_datums(path)
    assert sorted(truth) == ["B", "C"]
    datums = {d["name"]: d for d in pmi["datums"]}
    axes = {}
    for name, cyls in truth.items():
        d = datums[name]
        assert "unattached" not in d, d["unattached"]
        assert "ITEM_IDENTIFIED_REPRESENTATION_USAGE".replace("_", "").lower() in \
            d["attached"].replace("_", "").lower(), d["attached"]
        assert len(d["faces"]) == len(cyls) == 2           # one model face per STEP face
        p, a, r = cyls[0]
        a = a / np.linalg.norm(a)
        for c in cyls[1:]:                                 # the halves of one cylinder
            assert abs(c[2] - r) < 1e-9 and np.linalg.norm(np.cross(c[1], a)) < 1e-9
        for f in d["faces"]:
            v = np.asarray(pmi["face_vertices"][f], float)
            assert len(v) >= 2
            q = v - p
            dist = np.linalg.norm(q - np.outer(q @ a, a), axis=1)
            np.testing.assert_allclose(dist, r, atol=1e-6)
        axes[name] = (p, a)
    (pb, ab), (pc, ac) = axes["B"], axes["C"]
    q = pc - pb
    assert np.linalg.norm(q - (q @ ab) * ab) > 1.0         # B and C are different holes
    assert not set(datums["B"]["faces"]) & set(datums["C"]["faces"])


@pytest.mark.slow
def test_ctc01_plan_supports_the_tolerances_on_datums_b_and_c_and_lists_each_once(
        shared_data, ctc01_pmi, monkeypatch):
    from model_cache import load_model_stand_in, read_pmi_stand_in

    import shapeverify.cad.load
    import shapeverify.cad.pmi
    from shapeverify.characteristics import plan_from_pmi

    path, pmi = ctc01_pmi
    # the file's import and PMI from the suite's cache (bitwise load_model's and read_pmi's)
    monkeypatch.setattr(shapeverify.cad.load, "load_model", load_model_stand_in)
    monkeypatch.setattr(shapeverify.cad.pmi, "read_pmi", read_pmi_stand_in)
    plan = plan_from_pmi(path)
    chars = {c.pmi.id for c in plan.characteristics if c.pmi is not None}
    unsupported = Counter(u.pmi.id for u in plan.unsupported)
    assert all(n == 1 for n in unsupported.values()), unsupported
    assert not chars & set(unsupported)
    gts = {t["id"] for t in pmi["tolerances"]}
    assert gts == (chars | set(unsupported)) & gts           # every tolerance exactly once
    bc = {t["id"] for t in pmi["tolerances"]
          if {"B", "C"} & {d["name"] for d in t["datums"]}}
    assert len(bc) == 3                                       # two positions, a surface profile
    assert bc <= chars, [u.reason for u in plan.unsupported if u.pmi.id in bc]
    assert not [u for u in plan.unsupported if u.pmi.kind == "datum"]
    assert plan.alignment.type == "datums"


def test_usage_parameters_skip_strings_and_comments(tmp_path):
    from shapeverify.cad.pmi_iiru import _usage_records

    p = tmp_path / "x.stp"
    p.write_bytes(b"ISO-10303-21;\nDATA;\n"
                  b"#1=ITEM_IDENTIFIED_REPRESENTATION_USAGE('a;(#9)''',$,#35,/* #8, */#643,"
                  b"SET_REPRESENTATION_ITEM((#854,#853)));\n"
                  b"#2=GEOMETRIC_ITEM_SPECIFIC_USAGE('','DATUM',#34,#643,#861);\n"
                  b"#3=ITEM_IDENTIFIED_REPRESENTATION_USAGE('',$,#36,#643,(#1,#2);\n"
                  b"ENDSEC;\n")
    assert _usage_records(p) == [(1, 35, [854, 853]), (2, 34, [861])]


def test_a_usage_whose_item_is_not_a_face_of_the_model_keeps_the_datum_unattached_with_why(
        shared_data, tmp_path):
    from shapeverify.cad.pmi import read_pmi

    src = shared_data.joinpath(*CTC01)
    if not src.exists():
        pytest.skip(f"{src} not present (NIST MBE PMI test model)")
    text = src.read_bytes()
    old = b"SET_REPRESENTATION_ITEM((#854,#853))"
    assert text.count(old) == 1
    # datum B's usage names one of its faces and the cylindrical surface under the other
    bad = tmp_path / "ctc01_b_on_a_surface.stp"
    bad.write_bytes(text.replace(old, b"SET_REPRESENTATION_ITEM((#854,#3553))"))
    datums = {d["name"]: d for d in read_pmi(bad)["datums"]}
    b = datums["B"]
    assert b["faces"] == [] and "attached" not in b
    assert "ITEM_IDENTIFIED_REPRESENTATION_USAGE" in b["unattached"]   # the file's structure
    assert "CylindricalSurface" in b["unattached"], b["unattached"]    # the item that failed
    assert len(datums["C"]["faces"]) == 2                              # C still resolves
