"""The faces a PMI item controls, grouped into the features they make (issue 28).

Real CAD splits one cylinder into two or more faces (a seam, two half-cylinders) and one
plane into several coplanar faces (a floor cut by slots, four counterbore floors at one
depth); a drawing's tolerance or dimension on "the boss" or "the plane" names all of them.
A feature here is:

* **cylinder**: cylindrical faces on one axis line with one radius (:func:`cylinder_groups`);
* **plane**: planar faces in one plane, with the same outward normal (:func:`plane_groups`;
  ``oriented=False`` also joins faces of the plane whose normals are opposite).

The geometric tolerances are scaled to the feature and the part: radii equal within
``1e-4 x diameter + 1e-6``, axes parallel within 1e-4 rad and apart by at most
``1e-4 x diameter + 1e-7 x size``; planes parallel within 1e-6 (on the unit normals) and
apart by at most ``1e-6 x size + 1e-6`` mm -- CAD faces of one feature agree to rounding,
distinct features of a part differ by far more.

Example
-------
>>> import numpy as np
>>> from types import SimpleNamespace as F
>>> z = np.array([0.0, 0.0, 1.0])
>>> feats = [F(kind="plane", center=np.array([0.0, 0, 5]), axis=z),
...          F(kind="plane", center=np.array([9.0, 4, 5]), axis=z),
...          F(kind="plane", center=np.array([0.0, 0, 7]), axis=z)]
>>> plane_groups(feats, [0, 1, 2], size=100.0)
[[0, 1], [2]]
"""
from __future__ import annotations

import numpy as np

__all__ = ["cylinder_groups", "plane_groups", "same_cylinder", "same_plane", "features_of"]


def same_cylinder(f, g, size: float) -> bool:
    """Cylinder features ``f``, ``g`` (``center``, unit ``axis``, ``diameter``) lie on one
    cylinder: one radius, one axis line (module docstring's tolerances)."""
    d = float(g.diameter)
    q = np.asarray(f.center, float) - np.asarray(g.center, float)
    a = np.asarray(g.axis, float)
    off = float(np.linalg.norm(q - (q @ a) * a))
    return (abs(float(f.diameter) - d) <= 1e-4 * d + 1e-6
            and float(np.linalg.norm(np.cross(f.axis, a))) < 1e-4
            and off <= 1e-4 * d + 1e-7 * size)


def same_plane(f, g, size: float, oriented: bool = True) -> bool:
    """Planar features ``f``, ``g`` (``center``, unit outward normal ``axis``) lie in one
    plane (with the same outward side unless ``oriented`` is False)."""
    c = float(np.asarray(f.axis, float) @ np.asarray(g.axis, float))
    if abs(abs(c) - 1.0) > 1e-6 or (oriented and c < 0):
        return False
    return abs(float((np.asarray(f.center, float) - g.center) @ g.axis)) <= 1e-6 * size + 1e-6


def _groups(faces, same) -> list[list[int]]:
    out: list[list[int]] = []
    for f in faces:
        for g in out:
            if same(f, g[0]):
                g.append(f)
                break
        else:
            out.append([f])
    return out


def cylinder_groups(feats, faces, size: float) -> list[list[int]]:
    """The cylindrical ``faces`` (indices into ``feats``) grouped by the cylinder they lie on,
    in the order of their first face."""
    return _groups(faces, lambda i, j: same_cylinder(feats[i], feats[j], size))


def plane_groups(feats, faces, size: float, oriented: bool = True) -> list[list[int]]:
    """The planar ``faces`` grouped by the plane they lie in (see :func:`same_plane`)."""
    return _groups(faces, lambda i, j: same_plane(feats[i], feats[j], size, oriented))


def features_of(feats, faces, size: float) -> tuple[list[tuple[str, list[int]]], list[int]]:
    """([(kind, faces)] one per feature -- ``'cylinder'`` or ``'plane'`` groups, in the order
    of their first face --, the faces that are neither planar nor cylindrical)."""
    cyl = [f for f in faces if feats[f].kind == "cylinder"]
    pln = [f for f in faces if feats[f].kind == "plane"]
    groups = {g[0]: ("cylinder", g) for g in cylinder_groups(feats, cyl, size)}
    groups.update({g[0]: ("plane", g) for g in plane_groups(feats, pln, size)})
    order = [f for f in faces if f in groups]
    return [groups[f] for f in order], [f for f in faces if feats[f].kind not in
                                        ("cylinder", "plane")]
