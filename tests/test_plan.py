"""Inspection plans: the minimum contract is accepted exactly; errors name the line and the key."""
from __future__ import annotations

import pytest

from shapeverify.characteristics.plan import PlanError, load_plan, parse_plan

#: an RPS alignment and one characteristic of each of the first five types (also the seed of
#: the plan fuzzer, tests/test_fuzz_hostile.py)
EVERY_TYPE = """units: mm
part: A-0017
alignment:
  type: rps
  points:
    - {at: [20, 20, 0], lock: [z]}
    - {at: [80, 20, 0], lock: [z]}
    - {at: [50, 70, 0], lock: [z]}
    - {at: [30, 40, 0], lock: [x, y], feature: "hole:0"}
    - {at: [62, 22, 0], lock: [y]}
characteristics:
  - {name: H1, type: hole, feature: "hole:3", diameter: {lower: -0.1, upper: 0.3}}
  - {name: F, type: flatness, feature: "face:0", tol: 0.05}
  - {name: C, type: cylinder, near: [75, 58, 10], diameter: {tol: 0.1}}
  - {name: P1, type: check_point, at: [50, 60, 0], lower: -0.2, upper: 0.1, radius: 3}
  - {name: S, type: surface_profile, faces: ["face:0", 2], tol: 0.4, datum: false}
section: {point: [50, 40, 0], normal: [0, 1, 0], width: 2}
"""

CONTRACT = """units: mm
alignment: {type: best_fit}            # best_fit [faces: [...]] | constrained {free: [tx, ty, rz]} | rps {points: [{at: [x, y, z], lock: [z]}, ...]}
characteristics:
  - {name: H1, type: hole, near: [70, 55, 0], diameter: {tol: 0.2}, position: {tol: 0.3}}   # or feature: "hole:3"
  - {name: SKIN, type: surface_profile, faces: all, tol: 0.2}
"""


def test_minimum_contract_is_accepted_as_written_in_the_issue():
    p = parse_plan(CONTRACT)
    assert p.units == "mm"
    assert p.alignment.type == "best_fit" and p.alignment.faces == "all"
    h1, skin = p.characteristics
    assert (h1.name, h1.type, h1.near, h1.feature) == ("H1", "hole", [70.0, 55.0, 0.0], None)
    assert h1.diameter.limits() == (-0.2, 0.2) and h1.position.tol == 0.3
    assert (skin.name, skin.type, skin.faces, skin.tol) == ("SKIN", "surface_profile", "all", 0.2)


def test_every_alignment_and_characteristic_type_parses():
    p = parse_plan(EVERY_TYPE)
    assert p.part == "A-0017" and len(p.alignment.points) == 5
    assert p.alignment.points[3].lock == ["x", "y"]
    assert [c.type for c in p.characteristics] == ["hole", "flatness", "cylinder", "check_point",
                                                    "surface_profile"]
    assert p.characteristics[0].diameter.limits() == (-0.1, 0.3)
    assert p.characteristics[3].limits() == (-0.2, 0.1)
    assert p.section.width == 2.0
    c = parse_plan("alignment: {type: constrained, free: [tz, rz], center: [1, 2, 3]}\n")
    assert c.alignment.free == ["tz", "rz"] and c.alignment.center == [1.0, 2.0, 3.0]
    d = parse_plan("alignment: {type: datums, primary: 'face:0', secondary: 'hole:0', "
                   "tertiary: 'hole:1'}\n")
    assert (d.alignment.primary, d.alignment.tertiary) == ("face:0", "hole:1")


@pytest.mark.parametrize("text, line, key, words", [
    ("units: mm\ncharacteristics:\n  - name: H1\n    type: hole\n    near: [1, 2, 3]\n"
     "    diameter: {tol: abc}\n", 6, "characteristics[0].diameter.tol", "valid number"),
    ("units: mm\ncharacteristics:\n  - {name: S, type: surface_profile, tol: 0.2}\n"
     "  - {name: F, type: flatness, near: [1, 2, 3], tol: 0.1, colour: red}\n", 4,
     "characteristics[1].colour", "unknown key"),
    ("units: mm\ncharacteristics:\n\n  - {name: S, type: surfce_profile, tol: 0.2}\n", 4,
     "characteristics[0]", "surfce_profile"),
    ("units: mm\nalignment:\n  type: constrained\n  free: [tx, wz]\n", 4,
     "alignment.free[1]", "rz"),
    ("units: inch\n", 1, "units", "mm"),
    ("units: mm\ncharacteristics:\n  - {type: check_point, at: [0, 0, 0], tol: 0.1}\n", 3,
     "characteristics[0].name", "missing"),
    ("units: mm\ncharacteristics:\n  - {name: H, type: hole, near: [0, 0, 0]}\n", 3,
     "characteristics[0]", "diameter"),
])
def test_plan_errors_name_the_line_and_the_key(text, line, key, words):
    with pytest.raises(PlanError) as exc:
        parse_plan(text, source="plan.yaml")
    msg = str(exc.value)
    assert f"plan.yaml, line {line}, key '{key}'" in msg, msg
    assert words in msg
    assert exc.value.line == line and exc.value.key == key


def test_rps_with_too_few_locks_and_yaml_syntax_errors_name_their_line():
    with pytest.raises(PlanError, match=r"line 2, key 'alignment'.*lock 2 coordinates"):
        parse_plan("units: mm\nalignment:\n  type: rps\n  points:\n    - {at: [0, 0, 0], "
                   "lock: [x, z]}\n", source="plan.yaml")
    with pytest.raises(PlanError, match=r"plan.yaml, line 3: not valid YAML") as exc:
        parse_plan("units: mm\nalignment: {type: best_fit\n", source="plan.yaml")
    assert exc.value.line == 3
    with pytest.raises(PlanError, match="empty"):
        parse_plan("# nothing\n")


def test_load_plan_reads_files_dicts_and_text(tmp_path):
    f = tmp_path / "plan.yaml"
    f.write_text(CONTRACT)
    assert load_plan(f).characteristics[0].name == "H1"
    assert load_plan(str(f)) == load_plan(CONTRACT)
    assert load_plan({"alignment": {"type": "best_fit"}}).alignment.type == "best_fit"
    f.write_text("units: mm\ncharacteristics:\n  - {name: A, type: flatness, tol: -1, "
                 "feature: 'face:0'}\n")
    with pytest.raises(PlanError, match=r"plan.yaml, line 3, key 'characteristics\[0\].tol'"):
        load_plan(f)
    with pytest.raises(FileNotFoundError):
        load_plan(tmp_path / "missing.yaml")


def test_duplicate_names_and_contradictory_limits_are_refused():
    with pytest.raises(PlanError, match="used twice"):
        parse_plan("characteristics:\n  - {name: A, type: check_point, at: [0, 0, 0], tol: 1}\n"
                   "  - {name: A, type: check_point, at: [1, 0, 0], tol: 1}\n")
    with pytest.raises(PlanError, match="either tol or lower/upper"):
        parse_plan("characteristics:\n  - {name: A, type: check_point, at: [0, 0, 0], tol: 1, "
                   "lower: -1, upper: 1}\n")
    with pytest.raises(PlanError, match="must be below upper"):
        parse_plan("characteristics:\n  - {name: A, type: check_point, at: [0, 0, 0], "
                   "lower: 1, upper: -1}\n")
