"""Issue 30 item 6: ``--model-unit`` overrides the unit a CAD file declares, with a warning.

The bundled ``hammer.iges`` declares MM and is then about 40.9 m across; it could not be
corrected (``--model-unit`` was refused for CAD files).  Now the model is rescaled as if the
file had declared the given unit, and a warning names both units and the resulting size.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from typer.testing import CliRunner

import shapeverify as sv
from shapeverify.cad.model import Model
from shapeverify.cli import app
from shapeverify.nearest import load_prepared
from shapeverify.units import scale_model

pytest.importorskip("OCP")


def test_item6_hammer_declared_mm_read_as_micrometres(shared_data, caplog):
    path = shared_data / "cad" / "hammer.iges"
    model = sv.load_model(path)
    assert model.scale_to_mm == 1.0 and 40_000 < model.size < 42_000  # 40.9 m as declared
    with caplog.at_level(logging.WARNING, logger="shapeverify"):
        um = scale_model(model, "um")
    assert um.unit == "um" and um.scale_to_mm == 1e-3
    assert um.size == pytest.approx(model.size * 1e-3, rel=1e-12)
    np.testing.assert_allclose(um.bounds, model.bounds * 1e-3, rtol=1e-12)
    # the geometry itself: every face's surface points are the old ones x 1e-3
    rng = np.random.default_rng(3)
    for f0, f1 in zip(model.faces, um.faces):
        (u0, u1), (v0, v1) = f0.surface.domain
        u, v = rng.uniform(u0, u1, 5), rng.uniform(v0, v1, 5)
        np.testing.assert_allclose(f1.surface.evaluate(u, v), 1e-3 * f0.surface.evaluate(u, v),
                                   rtol=1e-12, atol=1e-12 * model.size)
        assert [lp.tobytes() for lp in f0.loops] == [lp.tobytes() for lp in f1.loops]
    # the bounds kept are those computed afresh on the scaled faces
    fresh = Model(faces=um.faces, unit=um.unit, scale_to_mm=um.scale_to_mm, source=um.source)
    np.testing.assert_allclose(fresh.bounds, um.bounds, rtol=0, atol=1e-9 * um.size)
    msg = " ".join(r.getMessage() for r in caplog.records)
    assert "hammer.iges" in msg and "--model-unit um" in msg and model.unit in msg
    assert f"{um.size:.4g} mm" in msg and f"{model.size:.4g} mm" in msg


def test_item6_info_and_prepare_accept_model_unit_for_cad(example_step, tmp_path, caplog):
    run = CliRunner()
    plain = sv.load_model(example_step)
    with caplog.at_level(logging.WARNING, logger="shapeverify"):
        res = run.invoke(app, ["info", str(example_step), "--model-unit", "in"])
    assert res.exit_code == 0, res.output
    flat = " ".join(res.output.split())
    assert f"{plain.size * 25.4:.3f}" in flat and "x25.4 to mm" in flat
    msg = " ".join(r.getMessage() for r in caplog.records)
    assert "panel.step: --model-unit in overrides the unit the file declares (millimetre" in msg
    assert f"{plain.size * 25.4:.4g} mm across" in msg
    res = run.invoke(app, ["info", str(example_step), "--features", "--model-unit", "in"])
    assert res.exit_code == 0 and f"{plain.size * 25.4:.3f}" in " ".join(res.output.split())
    out = tmp_path / "in.svm"
    res = run.invoke(app, ["prepare", str(example_step), "-o", str(out), "--model-unit", "in",
                           "--spacing", "20"])
    assert res.exit_code == 0, res.output
    prep = load_prepared(out)
    assert prep.model.unit == "in" and prep.model.scale_to_mm == 25.4
    assert prep.model.size == pytest.approx(plain.size * 25.4, rel=1e-9)
    # a unit of unknown size in the file cannot be overridden: a clear error
    odd = Model(faces=plain.faces, unit="furlong", scale_to_mm=float("nan"), source="x.step")
    with pytest.raises(ValueError, match="x.step.*no known size"):
        scale_model(odd, "mm")
