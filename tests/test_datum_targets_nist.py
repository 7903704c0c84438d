"""Datum targets, pattern and common datums, MMB datum shift and the reasons of unattached
datums on the NIST MBE PMI models (issue 28), each on an independent scan: OpenCASCADE's
tessellation of the STEP file, points uniform by area, 0.02 mm Gaussian noise along the
triangles' normals, a rigid motion (``tests/independent_scans.py``).

Each run evaluates only the characteristics under test (the plan's own alignment and its
``datums`` table, as ``shapeverify plan`` writes them):

* CTC 02: datums A (3 point targets), B (4), C (1) -> GT6-GT9 profiles in A|B|C; datum K (a
  circular area target of diameter 85) -> GT3 perpendicularity.  The scan covers the faces
  those and the plan's alignment need (every datum feature, targets, toleranced faces), at 1 mm: a perfect part passes them;
  GT9's face (206) moved 0.6 mm fails GT9 (0.75) only; GT3's face (203) tilted 0.6 degrees fails GT3 only
  (0.3 degrees: undecided).
* FTC 08: common datum E-F (two holes of the pattern) -> GT10 profile in D|E-F; a perfect part
  passes; both holes moved 0.35 mm move the frame (the profile grows by about 0.7 mm); the
  profile's faces moved 0.6 mm fail it.  GT17 (D|K(M)|L(M)): with
  hole K enlarged (a departure from its MMB) and the profile's faces moved, the shift brings
  the profile down by what the departure allows, against the same profile at RMB.
* FTC 06: pattern datum F (4 holes) -> GT8 position of 4 holes: a perfect part passes; one of
  them moved 0.5 mm fails it.
"""
from __future__ import annotations

import numpy as np
import pytest

pytestmark = [pytest.mark.slow, pytest.mark.shared]

NIST = ("cad", "nist")


def _gt_unsupported(data) -> int:
    return sum(u["pmi"]["kind"] == "geometric_tolerance" for u in data["unsupported"])


def _setup(shared_data, name, keep, faces=None, spacing=1.0):
    """(plan of the characteristics of PMI ids ``keep``, prepared model, scan points, their
    triangles' face (PMI numbering), the plan data, the model's features, fmap)."""
    from independent_scans import file_tessellation, random_points
    from model_cache import cached_model, cached_pmi, cached_prepared

    from shapeverify.cad.completeness import is_incomplete
    from shapeverify.characteristics.features import model_features
    from shapeverify.characteristics.plan import load_plan
    from shapeverify.characteristics.pmi_plan import _face_map, pmi_plan

    path = shared_data.joinpath(*NIST, name)
    if not path.exists():
        pytest.skip(f"{path} not present (NIST MBE PMI test model)")
    # the import, PMI, preparation and tessellation are built once per suite run and shared
    # with the other NIST modules (tests/model_cache.py: bitwise what load_model, read_pmi,
    # prepare and tessellate give)
    model = cached_model(path, features=True)
    r = pmi_plan(path, model=model, pmi=cached_pmi(path))
    data = dict(r.data)
    data["characteristics"] = [c for c in data["characteristics"] if c["pmi"]["id"] in keep]
    m = getattr(model, "model", model)
    # (allow_incomplete changes nothing for a complete model: then the other modules' entry)
    prep = cached_prepared(path, spacing=spacing, features=True,
                           **({"allow_incomplete": True} if is_incomplete(model) else {}))
    V, T, F = file_tessellation(path, 0.01)
    if faces is not None:
        T, F = T[np.isin(F, list(faces))], F[np.isin(F, list(faces))]
    rng = np.random.default_rng(0)
    P, N, t = random_points(V, T, spacing, rng, with_triangles=True)
    P = P + rng.normal(0.0, 0.02, len(P))[:, None] * N
    fmap = _face_map(r.pmi, m)
    inv = {v: k for k, v in fmap.items()}
    return dict(plan=load_plan(data), data=data, full=r.data, prep=prep, P=P, face=F[t],
                feats=model_features(m), fmap=fmap, inv=inv)


def _run(d, P, plan=None):
    from shapeverify.characteristics import evaluate_plan
    from shapeverify.characteristics.drf import rigid_exp

    M = rigid_exp([0.02, -0.01, 0.015, 3.0, -2.0, 1.0])
    res = evaluate_plan(d["prep"], P @ M[:3, :3].T + M[:3, 3], plan or d["plan"],
                        init=np.linalg.inv(M))
    assert res.alignment.details["converged"], res.alignment.details.get("reason")
    return {c.name: c for c in res.characteristics}


def _verdicts(res):
    return {n: c.verdict for n, c in res.items()}


def _tilt(P, sel, axis, degrees):
    from shapeverify.characteristics.drf import rigid_exp

    c = P[sel].mean(axis=0)
    R = rigid_exp(np.r_[np.radians(degrees) * np.asarray(axis, float), 0, 0, 0])[:3, :3]
    P = P.copy()
    P[sel] = (P[sel] - c) @ R.T + c
    return P


# ------------------------------------------------------------------------------ CTC 02
CTC02 = "nist_ctc_02_asme1_ap242-e1.stp"
CTC02_KEEP = ("GT3", "GT6", "GT7", "GT8", "GT9")


@pytest.fixture(scope="module")
def ctc02(shared_data):
    from model_cache import cached_pmi

    path = shared_data.joinpath(*NIST, CTC02)
    if not path.exists():
        pytest.skip(f"{path} not present")
    pmi = cached_pmi(path)
    by_id = {t["id"]: t for t in pmi["tolerances"]}
    faces = set()
    for d in pmi["datums"]:       # every datum: the plan's alignment (D|E|F) and the DRFs
        faces.update(d["faces"])
        for t in d["targets"]:
            faces.update(t["faces"])
    for k in CTC02_KEEP:
        faces.update(by_id[k]["faces"])
    return _setup(shared_data, CTC02, CTC02_KEEP, faces=faces)


def test_ctc02_datum_targets_give_the_plan_its_abc_and_k_frames(ctc02):
    dat = ctc02["full"]["datums"]
    assert [t["type"] for t in dat["A"]["targets"]] == ["point"] * 3
    assert [t["type"] for t in dat["B"]["targets"]] == ["point"] * 4
    assert [t["type"] for t in dat["C"]["targets"]] == ["point"]
    assert dat["K"]["targets"][0]["type"] == "circle"
    assert dat["K"]["targets"][0]["length"] == pytest.approx(85.0)
    ids = {c["pmi"]["id"] for c in ctc02["full"]["characteristics"]}
    assert set(CTC02_KEEP) <= ids
    # was 17 of 22 before datum targets, MMB/LMB shift and common datums (issue 28)
    assert _gt_unsupported(ctc02["full"]) <= 9


def test_ctc02_perfect_part_passes_its_target_datum_tolerances(ctc02):
    res = _run(ctc02, ctc02["P"])
    assert set(_verdicts(res).values()) == {"pass"}, {n: (c.verdict, c.measured, c.details.get(
        "reason")) for n, c in res.items()}
    assert res["GT3_perpendicularity"].details["drf"]["fits"][0]["kind"] == "plane"
    assert res["GT6_profile"].details["drf"]["free"] == []


def _face_of(d, name):
    """The model face of a plan entry with one face (read from the plan: the file's face
    numbers move when a face that failed to import is imported)."""
    (f,) = next(c for c in d["full"]["characteristics"] if c["name"] == name)["faces"]
    return int(f.split(":")[1])


def test_ctc02_face_moved_fails_its_profile_and_face_tilted_its_perpendicularity(ctc02):
    d = ctc02
    P = d["P"].copy()
    m9, m3 = _face_of(d, "GT9_profile"), _face_of(d, "GT3_perpendicularity")
    f9 = d["inv"][m9]
    n9 = d["feats"][m9].axis if d["feats"][m9].kind == "plane" else None
    assert n9 is not None
    P[d["face"] == f9] += 0.6 * n9
    f3 = d["inv"][m3]
    a3 = np.cross(d["feats"][m3].axis, [0.0, 1.0, 0.0])
    if np.linalg.norm(a3) < 0.1:
        a3 = np.cross(d["feats"][m3].axis, [1.0, 0.0, 0.0])
    P = _tilt(P, d["face"] == f3, a3 / np.linalg.norm(a3), 0.3)
    res = _run(d, P)
    v = _verdicts(res)
    # 0.3 degrees leaves GT3 (0.25) within its uncertainty: no longer a pass
    assert v["GT9_profile"] == "fail" and v["GT3_perpendicularity"] != "pass", v
    assert {n for n, x in v.items() if x == "fail"} == {"GT9_profile"}


def test_ctc02_face_tilted_0p6_degrees_fails_its_perpendicularity_to_k(ctc02):
    d = ctc02
    m3 = _face_of(d, "GT3_perpendicularity")
    f3 = d["inv"][m3]
    a3 = np.cross(d["feats"][m3].axis, [0.0, 1.0, 0.0])
    if np.linalg.norm(a3) < 0.1:
        a3 = np.cross(d["feats"][m3].axis, [1.0, 0.0, 0.0])
    P = _tilt(d["P"], d["face"] == f3, a3 / np.linalg.norm(a3), 0.6)
    v = _verdicts(_run(d, P))
    assert {n for n, x in v.items() if x == "fail"} == {"GT3_perpendicularity"}, v


# ------------------------------------------------------------------------------ FTC 08
FTC08 = "nist_ftc_08_asme1_ap242-e1.stp"


@pytest.fixture(scope="module")
def ftc08(shared_data):
    d = _setup(shared_data, FTC08, ("GT10", "GT17"))
    # the same GT17 at RMB, to see what the MMB shift gives
    import copy

    from shapeverify.characteristics.plan import load_plan

    data = copy.deepcopy(d["data"])
    rmb = copy.deepcopy(next(c for c in data["characteristics"] if c["pmi"]["id"] == "GT17"))
    rmb["name"] = "GT17_rmb"
    rmb.pop("datum_modifiers")
    data["characteristics"].append(rmb)
    d["plan"] = load_plan(data)
    return d


def test_ftc08_common_datum_e_f_frames_gt10(ftc08):
    d = ftc08
    assert d["full"]["datums"]["E-F"]["kind"] == "pattern"
    gt10 = next(c for c in d["full"]["characteristics"] if c["pmi"]["id"] == "GT10")
    assert gt10["datums"] == ["D", "E-F"]
    assert _gt_unsupported(d["full"]) <= 2       # was 4 of 33
    res = _run(d, d["P"])
    assert set(_verdicts(res).values()) == {"pass"}, _verdicts(res)
    assert res["GT10_profile"].details["drf"]["fits"][1]["kind"] == "pattern"
    # E and F (faces 61, 56) moved 0.35 mm across their axes: the frame follows them, the
    # profile's faces stay, so the profile grows by about twice that
    P = d["P"].copy()
    a = d["feats"][d["fmap"][61]].axis
    e = np.cross(a, [1.0, 0.0, 0.0])
    e /= np.linalg.norm(e)
    for f in (61, 56):
        P[d["face"] == f] += 0.35 * e
    r = _run(d, P)["GT10_profile"]
    assert r.measured == pytest.approx(res["GT10_profile"].measured + 0.7, abs=0.2), (
        r.measured, res["GT10_profile"].measured)


def test_ftc08_mmb_shift_lowers_the_profile_by_the_holes_departure(ftc08):
    """Holes K and L (faces 70, 72) 0.15 mm larger in radius than scanned (a departure from
    their MMB), the GT17 faces moved 0.1 mm across K's axis: at RMB the profile sees the
    0.1 mm; at MMB the frame may shift by the departure (reported in details) and takes it
    back."""
    d = ftc08
    P = d["P"].copy()
    for f in (70, 72):                  # K and L, both at MMB in GT17
        h = d["feats"][d["fmap"][f]]
        sel = d["face"] == f
        q = P[sel] - h.center
        radial = q - np.outer(q @ h.axis, h.axis)
        P[sel] += 0.15 * radial / np.linalg.norm(radial, axis=1)[:, None]
    k = d["feats"][d["fmap"][70]]
    e = np.cross(k.axis, [1.0, 0.0, 0.0])
    e /= np.linalg.norm(e)
    gt17 = next(c for c in d["full"]["characteristics"] if c["pmi"]["id"] == "GT17")
    for f in gt17["faces"]:
        P[d["face"] == d["inv"][int(f.split(":")[1])]] += 0.1 * e
    # and GT10's faces moved 0.6 mm: it fails (1.016 zone)
    gt10 = next(c for c in d["full"]["characteristics"] if c["pmi"]["id"] == "GT10")
    for f in gt10["faces"]:
        P[d["face"] == d["inv"][int(f.split(":")[1])]] += 0.6 * e
    res = _run(d, P)
    assert res["GT10_profile"].verdict == "fail", res["GT10_profile"].measured
    mmb, rmb = res["GT17_profile"], res["GT17_rmb"]
    sh = mmb.details["datum_shift"]
    assert sh["datums"]["K"]["shift_radius"] > 0.05, sh
    assert sh["applied"]
    # each shifted datum's axis moves across itself by no more than its shift radius (the
    # motion acts in the DRF frame, where the datum axes sit on the CAD's)
    w, t = np.array(sh["motion"][:3]), np.array(sh["motion"][3:])
    for name, f in (("K", 70), ("L", 72)):
        h = d["feats"][d["fmap"][f]]
        move = np.cross(w, h.center) + t
        move -= (move @ h.axis) * h.axis
        assert np.linalg.norm(move) <= sh["datums"][name]["shift_radius"] + 1e-6, name
    assert mmb.measured < rmb.measured - 0.05, (mmb.measured, rmb.measured)


# ------------------------------------------------------------------------------ FTC 06
FTC06 = "nist_ftc_06_asme1_ap242-e1.stp"


@pytest.fixture(scope="module")
def ftc06(shared_data):
    return _setup(shared_data, FTC06, ("GT8",))


def test_ftc06_pattern_datum_f_frames_the_position_of_four_holes(ftc06):
    d = ftc06
    assert d["full"]["datums"]["F"]["kind"] == "pattern"
    assert _gt_unsupported(d["full"]) <= 6       # was 7 of 27
    res = _run(d, d["P"])
    assert res["GT8_position"].verdict == "pass", res["GT8_position"].details
    # one of the four holes (faces 185, 186) moved 0.5 mm: twice that against 0.508
    P = d["P"].copy()
    h = d["feats"][d["fmap"][185]]
    e = np.cross(h.axis, [1.0, 0.0, 0.0])
    if np.linalg.norm(e) < 0.1:
        e = np.cross(h.axis, [0.0, 1.0, 0.0])
    e /= np.linalg.norm(e)
    for f in (185, 186):
        P[d["face"] == d["inv"][f]] += 0.5 * e
    r = _run(d, P)["GT8_position"]
    assert r.verdict == "fail", (r.measured, r.upper, r.uncertainty)


# ------------------------------------------------------------------------------ reasons
# (NIST CTC 01's datums B and C, tied by ITEM_IDENTIFIED_REPRESENTATION_USAGE, are attached
# now: tests/test_pmi_iiru.py; FTC 06's G and H, set up from 'circular curve' targets that
# XCAF does not read, are read from the STEP entities: tests/test_datum_targets_ftc06.py)
@pytest.mark.parametrize("name,letters,what", [
    ("nist_ftc_06_asme1_ap242-e1.stp", "GH", "'circular curve'"),
])
def test_datums_of_targets_xcaf_does_not_read_say_how_the_file_attaches_them(
        shared_data, name, letters, what):
    from model_cache import cached_pmi

    path = shared_data.joinpath(*NIST, name)
    if not path.exists():
        pytest.skip(f"{path} not present")
    pmi = cached_pmi(path)
    got = {d["name"]: d.get("unattached") or "; ".join(t.get("attached", "") for t in
                                                       d["targets"]) for d in pmi["datums"]}
    for L in letters:
        assert what in got[L], got[L]
