"""A point datum target that the file attaches to a vertex (a standalone point: NIST CTC 02 in
AP242 edition 2, CATIA's 'Point.5' ... for datum A) was "attached to vertexs, not to one face",
and every tolerance referencing A|B|C (GT3-5, GT13, GT20, GT21) stayed unsupported. It is put on
the one face whose trimmed domain holds the point; on an edge, the one whose normal is along the
target's direction."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from partial_view_proxies import box_model
from shapeverify.characteristics.pmi_datums import targets_spec


def _spec(at, direction):
    m = box_model()                    # [-50, 50] x [-30, 30] x [-20, 20]
    ctx = SimpleNamespace(size=100.0, model=m, feats=None,
                          fmap={k: k for k in range(len(m.faces))})
    t = {"type": "Point", "number": 1, "faces": [], "other": ["vertex"], "at": list(at),
         "direction": list(direction)}
    spec, why = targets_spec({"name": "A", "targets": [t]}, ctx, {"name": "A"})
    return m, spec, why


def _plane(m, face):
    f = m.faces[int(face.split(":")[1])]
    (a0, a1), (b0, b1) = f.uv_bounds
    p = f.evaluate(np.array([[0.5 * (a0 + a1), 0.5 * (b0 + b1)]]))[0]
    return np.round(p, 6)


def test_point_target_attached_to_a_vertex_is_put_on_the_face_holding_it():
    m, spec, why = _spec([10.0, 5.0, -20.0], [0.0, 0.0, 1.0])
    assert why == "" and len(spec["targets"]) == 1
    e = spec["targets"][0]
    assert e["type"] == "point" and e["at"] == [10.0, 5.0, -20.0]
    assert _plane(m, e["face"])[2] == -20.0
    assert "attached to a point (vertex)" in spec["pmi"]["targets_from_geometry"][0]


def test_point_target_on_an_edge_takes_the_face_along_its_direction():
    m, spec, _ = _spec([50.0, 5.0, -20.0], [0.0, 0.0, -1.0])
    assert _plane(m, spec["targets"][0]["face"])[2] == -20.0
    m, spec, _ = _spec([50.0, 5.0, -20.0], [1.0, 0.0, 0.0])
    assert _plane(m, spec["targets"][0]["face"])[0] == 50.0
    _, spec, why = _spec([50.0, 5.0, -20.0], [0.6, 0.0, 0.8])
    assert spec is None and "lies on 0 faces" in why


def test_point_target_off_the_part_stays_unsupported_with_the_reason():
    _, spec, why = _spec([0.0, 0.0, -25.0], [0.0, 0.0, 1.0])
    assert spec is None and "target A1 (Point)" in why and "lies on 0 faces" in why
