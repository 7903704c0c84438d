"""Position with a maximum tolerance (ASME Y14.5-2009 §7.3.4, "MAX" in the frame: the limit is
min(tol + bonus, max_tol)) and with a projected tolerance zone (§7.4.1, Ⓟ: the zone holds the
axis extended out of the hole's mouth over the projection length), on synthetic holes whose
answers are computed by hand / by brute force here."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.characteristics import gdt
from shapeverify.characteristics.features import Feature
from shapeverify.characteristics.schema import Position


def _hole_points(diameter, offset=(0.0, 0.0), tilt=0.0, depth=20.0, n_around=72, n_up=41):
    """Points (and inward normals) of a perfect hole wall of ``diameter`` going down from its
    mouth at z = 0 to z = -depth: its axis crosses the mouth plane at ``offset`` (x, y) and
    leans by ``tilt`` radians towards +x going up (out of the mouth).  A section normal to
    the tilted axis is a circle (the wall is a right cylinder about the tilted axis)."""
    a = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    u = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    v = np.array([0.0, 1.0, 0.0])
    p0 = np.array([offset[0], offset[1], 0.0])
    t = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    s = np.linspace(-depth / np.cos(tilt), 0.0, n_up)
    T, Sx = np.meshgrid(t, s)
    T, Sx = T.ravel(), Sx.ravel()
    radial = np.outer(np.cos(T), u) + np.outer(np.sin(T), v)
    X = p0 + np.outer(Sx, a) + 0.5 * diameter * radial
    return X, -radial


def _ctx(X, N, feat, monkeypatch, rim=None):
    """A minimal evaluation context of one cylinder face 0 holding every point."""
    S = SimpleNamespace(X=X, normals=N, noise=0.0)
    monkeypatch.setattr(gdt, "_on", lambda ctx, faces: np.ones(len(X), bool))
    monkeypatch.setattr(gdt, "_feature_faces", lambda ref, ctx: [0])
    if rim is not None:
        monkeypatch.setattr(gdt, "_faces_rim", lambda ctx, fidx: rim)
    return SimpleNamespace(S=S, feats={0: feat}, k=2.0, prep=None, cache={}, plan=None)


_CAD = Feature("face:0", "cylinder", 0, np.array([0.0, 0.0, -10.0]), np.array([0.0, 0.0, 1.0]),
               10.0)


def test_position_max_tol_caps_a_bonus_that_would_pass_the_hole(monkeypatch):
    """A hole of nominal 10 (size 0 / +0.5, MMC 10) made 10.4 and 0.2 off: by hand the bonus
    is 10.4 - 10 = 0.4, the uncapped limit 0.1 + 0.4 = 0.5 holds the measured 2 x 0.2 = 0.4;
    with MAX 0.3 the limit is min(0.5, 0.3) = 0.3 and the hole fails (FTC 07 GT7 / GT17:
    the cap was dropped and the bonus unlimited)."""
    X, N = _hole_points(10.4, offset=(0.2, 0.0))
    ctx = _ctx(X, N, _CAD, monkeypatch)
    base = dict(type="position", name="P", features=["face:0"], tol=0.1, material="M",
                size={"lower": 0.0, "upper": 0.5})
    free = gdt.eval_position(Position(**base), ctx)
    capped = gdt.eval_position(Position(**base, max_tol=0.3), ctx)
    bonus = 10.4 - 10.0
    assert free.details["features"][0]["bonus"] == pytest.approx(bonus, abs=1e-6)
    assert free.measured == pytest.approx(0.4, abs=1e-6)
    assert free.upper == pytest.approx(0.1 + bonus, abs=1e-6)
    assert free.verdict == "pass"
    assert capped.upper == pytest.approx(min(0.1 + bonus, 0.3), abs=1e-9)
    assert capped.measured == pytest.approx(0.4, abs=1e-6)
    assert capped.verdict == "fail"


def test_position_max_tol_leaves_a_bonus_under_the_cap_alone(monkeypatch):
    """Made 10.1: bonus 0.1, limit 0.2 < MAX 0.3: the cap does not bind."""
    X, N = _hole_points(10.1, offset=(0.05, 0.0))
    ctx = _ctx(X, N, _CAD, monkeypatch)
    r = gdt.eval_position(Position(type="position", name="P", features=["face:0"], tol=0.1,
                                   material="M", size={"lower": 0.0, "upper": 0.5},
                                   max_tol=0.3), ctx)
    assert r.upper == pytest.approx(0.2, abs=1e-6)
    assert r.verdict == "pass"


def test_position_max_tol_needs_a_material_modifier_and_no_less_than_tol():
    with pytest.raises(ValueError, match="max_tol"):
        Position(type="position", name="P", features=["face:0"], tol=0.1, max_tol=0.3)
    with pytest.raises(ValueError, match="max_tol"):
        Position(type="position", name="P", features=["face:0"], tol=0.4, material="M",
                 size={"lower": 0.0, "upper": 0.5}, max_tol=0.3)
