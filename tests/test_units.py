"""Units of files that carry none (issue 14 item 5): name the factor that fits, let the user set it."""

from __future__ import annotations

import numpy as np
import pytest

from shapeverify.cad.model import Model
from shapeverify.units import scale_model, scale_points, unit_factor, unit_hint


@pytest.mark.parametrize("factor, unit, flag", [(10.0, "centimetres", "--scan-unit cm"),
                                                (25.4, "inches", "--scan-unit in"),
                                                (1000.0, "metres", "--scan-unit m")])
def test_scan_in_another_unit_names_the_factor(factor, unit, flag):
    hint = unit_hint(scan_size=0.7 * 360.0 / factor, model_size=360.0)
    assert unit in hint and flag in hint


def test_model_in_centimetres_names_the_model_flag():
    hint = unit_hint(scan_size=250.0, model_size=36.0)
    assert "model is in centimetres" in hint and "--model-unit cm" in hint


def test_no_hint_for_a_plausible_partial_view():
    assert unit_hint(scan_size=100.0, model_size=360.0) is None
    assert unit_hint(scan_size=360.0, model_size=360.0) is None


def test_unknown_unit_is_a_clear_error():
    with pytest.raises(ValueError, match="use one of mm, cm, m, in, um"):
        unit_factor("furlong")


def test_scale_points_and_mesh_model():
    np.testing.assert_allclose(scale_points([[1.0, 2.0, 3.0]], "in"), [[25.4, 50.8, 76.2]])
    mesh = Model((), source="tri.stl", kind="mesh", vertices=np.eye(3),
                 triangles=np.array([[0, 1, 2]], np.int32))
    cm = scale_model(mesh, "cm")
    np.testing.assert_allclose(cm.vertices, 10 * np.eye(3))
    assert cm.scale_to_mm == 10.0 and cm.unit == "cm"


def test_cad_model_unit_overrides_the_declared_unit():
    # issue 30 item 6 (was: refused); more in tests/test_cad_model_unit.py
    from shapeverify.cad.model import Face
    from shapeverify.cad.nurbs import sphere

    f = Face(sphere(2.0), (np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]),), (np.zeros(4, bool),))
    cm = scale_model(Model((f,), source="part.step"), "cm")
    assert cm.unit == "cm" and cm.scale_to_mm == 10.0
    np.testing.assert_allclose(cm.faces[0].surface.control, 10 * f.surface.control)
