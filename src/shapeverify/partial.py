"""Partial references: inspect against a region of a mesh or point-cloud reference.

A mesh (STL/PLY/OBJ) or point-cloud reference has no CAD faces to choose with ``faces=``, so a
scan that sees a part of it (a gear's rim, one side of a box) can only be ``incomplete``: the
coverage counts the whole reference.  :func:`inspect_partial` limits the reference first:

* ``box=(lo, hi)``: the triangles whose centroid (the points) inside an axis-aligned box of model
  coordinates (mm);
* ``seen=True``: the part of the reference the scan saw: the scan is registered and measured
  against the whole reference, then the reference is limited to the triangles that hold an
  evaluated foot point (for a cloud: the reference points within two spacings of one) and the
  scan is evaluated again at the same pose.  Coverage is then that of the seen part, by
  construction high: the verdict says so in its reasons, so a reader knows that the part's
  other surfaces were not measured.

Scan points whose closest point lies past the limited reference's outline are not evaluated
(``on_boundary``: a mesh foot on an edge of one triangle only, a cloud foot with no reference
point near it), as past a CAD part's free edges.  The result's second reason names the region.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
from shapeverify._lazy import cKDTree

logger = logging.getLogger(__name__)

__all__ = ["crop_model", "inspect_partial"]


def _kind(model) -> str:
    kind = getattr(model, "kind", "cad")
    kind = getattr(kind, "value", kind)
    if kind not in ("mesh", "points"):
        raise ValueError(f"a partial reference needs a mesh or point-cloud model, got a {kind!r} "
                         "model; for a CAD model choose its faces instead (inspect(faces=[...]), or "
                         "inspect(faces=\"seen\") for the faces the scan saw)")
    return kind


def crop_model(model, box=None, keep=None):
    """The part of a mesh or point-cloud model inside ``box`` or chosen by ``keep``.

    Parameters
    ----------
    model : Model with ``kind`` "mesh" or "points"
    box : ((3,), (3,)) array_like, optional
        Lower and upper corner (model coordinates, mm): triangles whose centroid lies inside
        (points inside) are kept.
    keep : (T,) or (V,) bool array_like, optional
        The triangles (mesh) or points (cloud) to keep, instead of ``box``.

    Returns
    -------
    Model
        A model of the same kind with the kept triangles (their vertices re-indexed) or points
        (and their normals); ``source`` says what was kept.

    Raises
    ------
    ValueError
        If the model is a CAD model, neither or both of box and keep are given, the box is not
        two finite corners with lo < hi, or nothing would be kept.
    """
    kind = _kind(model)
    if (box is None) == (keep is None):
        raise ValueError("give either box=(lo, hi) or keep= (a mask), not both or neither")
    V = np.asarray(model.vertices, dtype=np.float64)
    items = V if kind == "points" else V[np.asarray(model.triangles)].mean(axis=1)
    if box is not None:
        try:
            lo, hi = (np.asarray(c, dtype=np.float64).reshape(3) for c in box)
        except (TypeError, ValueError):
            raise ValueError(f"box must be two corners ((x, y, z), (x, y, z)) in mm, got {box!r}") \
                from None
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
            raise ValueError(f"box must have finite corners with lower < upper on every axis, "
                             f"got lower {lo.tolist()}, upper {hi.tolist()}")
        mask = np.all((items >= lo) & (items <= hi), axis=1)
        what = f"the box {lo.round(3).tolist()} .. {hi.round(3).tolist()} mm"
    else:
        mask = np.asarray(keep, dtype=bool).reshape(-1)
        if mask.shape[0] != items.shape[0]:
            what = "point" if kind == "points" else "triangle"
            raise ValueError(f"keep must have one entry per {what} ({items.shape[0]}), got "
                             f"{mask.shape[0]}")
        what = "a chosen region"
    n = int(mask.sum())
    unit = "points" if kind == "points" else "triangles"
    if n == 0:
        raise ValueError(f"no {unit} of {getattr(model, 'source', 'the model')} lie in {what}: "
                         "check the region's coordinates (model coordinates, mm)")
    source = f"{getattr(model, 'source', '')} ({n} of {items.shape[0]} {unit} in {what})"
    if kind == "points":
        normals = None if model.cloud_normals is None else np.asarray(model.cloud_normals)[mask]
        return dataclasses.replace(model, vertices=V[mask], cloud_normals=normals, source=source)
    T = np.asarray(model.triangles)[mask]
    used, T_new = np.unique(T, return_inverse=True)
    return dataclasses.replace(model, vertices=V[used],
                               triangles=T_new.reshape(T.shape).astype(np.int32), source=source)


def _mesh_area(model) -> float:
    V = np.asarray(model.vertices, dtype=np.float64)
    T = np.asarray(model.triangles)
    return float(0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]),
                                      axis=1).sum())


def _describe(full, part, how: str) -> str:
    if _kind(full) == "mesh":
        a, b = _mesh_area(part), _mesh_area(full)
        size = (f"{len(part.triangles)} of {len(full.triangles)} triangles, {a:.0f} of "
                f"{b:.0f} mm² ({100 * a / b:.0f} %)")
    else:
        size = f"{len(part.vertices)} of {len(full.vertices)} reference points"
    return (f"reference limited to {how} ({size}): coverage and verdict are of that region only; "
            "the rest of the part was not measured")


def inspect_partial(prep, scan, *, box=None, seen: bool = False, spacing: float | None = None,
                    **inspect_kwargs):
    """Inspect a scan against a region of a mesh or point-cloud reference (see the module).

    Parameters
    ----------
    prep : Prepared
        The whole reference, prepared (its model is ``prep.model``).
    scan : (N, 3) array_like
    box : ((3,), (3,)), optional
        Limit the reference to this box (model coordinates, mm) before inspecting.
    seen : bool
        Limit the reference to the part the scan saw (after registering against the whole).
    spacing : float, optional
        Model point spacing of the limited reference (default: that of ``prep``).
    **inspect_kwargs
        As :func:`shapeverify.inspect` (tolerance, init, ...).

    Returns
    -------
    InspectionResult
        Its second reason names the region the verdict is about.

    Raises
    ------
    ValueError
        If the reference is a CAD model, neither or both of ``box`` and ``seen`` are given, or
        the region holds nothing; and as :func:`shapeverify.inspect`.
    """
    from shapeverify.inspection import inspect, inspect_registered
    from shapeverify.nearest import prepare

    model = prep.model
    _kind(model)
    if (box is None) == (not seen):
        raise ValueError("give either box=(lo, hi) or seen=True")
    spacing = float(prep.model_spacing if spacing is None else spacing)
    if box is not None:
        part = crop_model(model, box=box)
        lo, hi = (np.asarray(c, dtype=np.float64).reshape(3) for c in box)
        result = inspect(prepare(part, spacing=spacing), scan, **inspect_kwargs)
        return _with_note(result, _describe(model, part, f"the box {lo.round(3).tolist()} .. "
                                                         f"{hi.round(3).tolist()} mm"))
    whole = inspect(prep, scan, **inspect_kwargs)
    if whole.rule in ("registration", "no_data"):
        return whole                  # no pose to see anything from: the whole-reference answer
    dev = whole.deviations
    ev = np.flatnonzero(dev.evaluated)
    if _kind(model) == "mesh":
        keep = np.zeros(len(model.triangles), dtype=bool)
        keep[np.asarray(dev.face)[ev]] = True
    else:
        reach = 2.0 * max(spacing, float(whole.scan_spacing) if np.isfinite(whole.scan_spacing) else 0.0)
        near, _ = cKDTree(np.asarray(dev.foot_points)[ev]).query(
            np.asarray(model.vertices, dtype=np.float64), distance_upper_bound=reach)
        keep = np.isfinite(near)
    part = crop_model(model, keep=keep)
    opts = {k: v for k, v in inspect_kwargs.items()
            if k in ("evaluation_distance", "min_coverage", "min_region_points",
                     "min_inlier_fraction", "max_distance")}   # (its deprecated old name)
    result = inspect_registered(prepare(part, spacing=spacing), scan, whole.registration,
                                tolerance=whole.tolerance, **opts)
    logger.info("partial reference: %s", part.source)
    return _with_note(result, _describe(model, part, "the part the scan saw"))


def _with_note(result, note: str):
    reasons = tuple(result.reasons)
    return dataclasses.replace(result, reasons=reasons[:1] + (note,) + reasons[1:])
