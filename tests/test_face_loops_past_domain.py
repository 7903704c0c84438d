"""NIST FTC 07: many faces' pcurves run past their surface's domain (1e-5 .. 2e-3 of its width;
0.35 rad on a sphere patch by its pole after ``BRepBuilderAPI_NurbsConvert``), so evaluating
the face's own loops or a grid over their box raised "u must lie in the domain" in
``features`` (``_face_grid``, ``_cylinder_holes``) and ``shapeverify plan`` failed.  A face now
puts values past the domain but within its trims' box on the domain's edge (as the import
evaluated the loops); values beyond the trims' box are still refused."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.cad.model import Face
from shapeverify.cad.nurbs import NurbsSurface


def _plane_face(excess: float) -> Face:
    k = np.array([0.0, 0.0, 1.0, 1.0])
    ctrl = np.array([[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]])
    surf = NurbsSurface(1, 1, k, k, ctrl)
    loop = np.array([[0.0, 0.0], [1.0 + excess, 0.0], [1.0 + excess, 1.0], [0.0, 1.0]])
    return Face(surf, (loop,), (np.ones(4, bool),))


def test_face_evaluates_its_loops_past_the_domain_on_the_domains_edge():
    f = _plane_face(2e-3)
    X = f.evaluate(f.loops[0])
    assert np.allclose(X[:, 0], [0.0, 1.0, 1.0, 0.0])
    assert np.allclose(f.normal(f.loops[0]), [0.0, 0.0, 1.0])
    (a0, a1), _ = f.uv_bounds
    g = np.column_stack([np.linspace(a0, a1, 5), np.full(5, 0.5)])
    assert f.evaluate(g)[-1, 0] == pytest.approx(1.0)


def test_face_still_refuses_parameters_beyond_its_trims():
    f = _plane_face(2e-3)
    with pytest.raises(ValueError, match="domain"):
        f.evaluate([[1.01, 0.5]])
    inside = _plane_face(0.0)
    with pytest.raises(ValueError, match="domain"):
        inside.evaluate([[1.001, 0.5]])
