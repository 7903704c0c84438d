"""The reason an All Around orientation tolerance on a contour stays unsupported names the
contour's faces (NIST FTC 10 GT11: an obround's two planar sides square to datum H and two
half-cylinders R7.5 whose axes run along H's normal), on a hand-built feature table."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from shapeverify.characteristics.pmi_all_around import all_around_reason


def _f(kind, axis, diameter=None):
    return SimpleNamespace(kind=kind, axis=np.asarray(axis, float), diameter=diameter)


def test_all_around_reason_names_the_obround_contour_against_its_datum_plane():
    feats = {83: _f("plane", [0, 1, 0]), 180: _f("plane", [0, 0, 1]),
             178: _f("plane", [0, 0, -1]), 177: _f("cylinder", [0, -1, 0], 15.0),
             179: _f("cylinder", [0, 1, 0], 15.0)}
    ctx = SimpleNamespace(feats=feats, datum_specs={"H": {"kind": "plane",
                                                          "faces": ["face:83"]}})
    item = {"datums": [{"name": "H", "order": 1, "modifiers": []}]}
    r = all_around_reason(item, ctx, [180, 178, 177, 179], "modifier All_Around")
    assert "4 faces around a contour (2 cylinder, 2 plane)" in r
    assert "face:180 plane square to the datum" in r and "face:178 plane square" in r
    assert r.count("part-cylinder R7.5, axis along the datum's normal") == 2


def test_all_around_reason_of_planes_only_says_each_face_is_not_planned():
    feats = {1: _f("plane", [1, 0, 0]), 2: _f("plane", [0, 1, 0])}
    ctx = SimpleNamespace(feats=feats, datum_specs={})
    r = all_around_reason({"datums": []}, ctx, [1, 2], "x")
    assert r.endswith("each face's zone separately is not planned")
