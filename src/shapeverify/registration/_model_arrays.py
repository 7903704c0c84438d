"""The model points registration works with: their arrays once per prepared model, the exact
points behind fast answers, and a solid of revolution's spin (see :func:`._irls.null_directions`)."""
from __future__ import annotations

import weakref

import numpy as np

__all__ = ["ModelArrays", "model_points", "information_points", "spin_direction", "SPIN_DEG"]


class ModelArrays(tuple):
    """(points, normals) (M, 3) of a prepared model, with ``kind`` ("cad", "mesh", "points")
    and ``size`` (mm) of its model; ``spin`` caches its axis of revolution (see
    :func:`spin_direction`)."""


_MODEL_ARRAYS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def model_points(prep):
    """(points, normals) (M, 3) of the model points ``Closest.index`` refers to, or None
    (a :class:`ModelArrays`, made once per Prepared model).

    ``prep.points`` is assembled once per Prepared model (and its arrays are C-contiguous
    float64, so nothing is copied here).
    """
    try:
        return _MODEL_ARRAYS[prep]
    except (KeyError, TypeError):
        pass
    mp = getattr(prep, "points", None)
    if mp is None or not hasattr(mp, "normals"):
        return None
    out = ModelArrays((np.ascontiguousarray(mp.points, np.float64),
                       np.ascontiguousarray(mp.normals, np.float64)))
    model = getattr(prep, "model", None)
    out.kind = str(getattr(getattr(model, "kind", None), "value", getattr(model, "kind", "")))
    out.size = float(getattr(model, "size", 0.0) or 0.0)
    try:
        _MODEL_ARRAYS[prep] = out
    except TypeError:   # not weak-referenceable
        pass
    return out


#: a mesh's or a cloud's weakest direction within this angle (deg) of a spin about its model's
#: axis of revolution counts as undetermined (see null_directions)
SPIN_DEG = 5.0
#: ... unless FEATURES of its model points have normals FEATURE_DEG or more out of the plane
#: through the axis: a feature that fixes the spin (a keyway 6 x 3 x 25 mm on a 127 mm turned
#: part: 0.6 % of the points), which the facets of a solid of revolution do not give
FEATURES, FEATURE_DEG = 0.001, 15.0


def spin_direction(mp, center, radius):
    """The spin about the model's axis of revolution as a scaled direction (6,) about
    ``center`` (as the eigenvectors of :func:`null_directions`), or None: a mesh or a cloud
    whose model is a solid of revolution (:func:`._revolution.model_axis`) with no feature
    across the spin (:func:`_across_share`) only."""
    if getattr(mp, "kind", "cad") not in ("mesh", "points"):
        return None
    if not hasattr(mp, "spin"):
        from types import SimpleNamespace

        from . import _revolution
        M, Nm = mp
        s = max(1, M.shape[0] // 5000)
        size = mp.size or float(np.linalg.norm(np.ptp(M, axis=0)))
        mp.spin = _revolution.model_axis(SimpleNamespace(axes_points=M[::s],
                                                         axes_normals=Nm[::s], size=size))
        if mp.spin is not None and _across_share(M[::s], Nm[::s], mp.spin) >= FEATURES:
            mp.spin = None      # a keyway, a flat: the spin is the part's to fix, not free
    if mp.spin is None:
        return None
    a, p, _ = mp.spin
    u = np.r_[a * radius, np.cross(p - center, a)]
    return u / np.linalg.norm(u)


def _across_share(M, Nm, spin) -> float:
    """Share of the model points whose normals lie at least :data:`FEATURE_DEG` out of the
    plane through the axis of ``spin`` (a keyway's walls; a mesh's facets of a solid of
    revolution tilt by a few degrees).

    >>> a = (np.array([0, 0, 1.0]), np.zeros(3), (0.0, 1.0))
    >>> M = np.array([[10.0, 0, 0], [0, 10.0, 0], [10.0, 1.0, 0], [10.0, -1.0, 0]])
    >>> Nm = np.array([[1.0, 0.03, 0], [-0.03, 1.0, 0], [0.0, 1.0, 0], [0.0, 0.0, 1.0]])
    >>> _across_share(M, Nm, a)
    0.25
    """
    from ._revolution import normal_misfit

    miss, _ = normal_misfit(M, Nm, spin[0], spin[1])
    return float(np.mean(miss >= np.sin(np.radians(FEATURE_DEG))))


def information_points(ev, mp):
    """Exact surface points and normals (the nearest model points) for the information matrix.

    The feet of the fast closest points lie on tangent patches, off the surface by up to
    spacing^2 x curvature, which gives e.g. a cylinder's rotation about its axis some spurious
    information; the model points themselves lie on the surface with exact normals.
    """
    if mp is None or not np.all(ev.index[ev.valid] >= 0):
        return ev.Y, ev.N
    i = np.where(ev.valid, ev.index, 0)
    valid = ev.valid[:, None]
    return (np.where(valid, mp[0][i], ev.X), np.where(valid, mp[1][i], 0.0))
