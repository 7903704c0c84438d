"""Coverage: how much of the inspected CAD area the scan actually saw.

An inspection can only vouch for the surface it measured.  The inspected area (all faces, or the
faces the user names) is represented by up to ``MAX_SAMPLES`` of the prepared model points (an
evenly spread subset: they are in Morton order, so every k-th point is spread over the whole
model; the model points are sampled at a uniform spacing, so each stands for the same area).
A model point is **covered** when an *evaluated* scan point (its foot point on the CAD) lies
within the coverage radius ``r`` of it, with

    r = max(2 x model spacing, min(2 x scan spacing, 1 % of the model size))

(scan spacing: median distance between neighbouring evaluated foot points).  The cap keeps a
sparse scan from "covering" the part: 20 points on a 300 x 200 mm panel cover about 1 % of it.

``fraction`` is the covered share of the inspected area; ``per_face`` the same per face; the
uncovered area is returned as a map (``points``, ``covered``) and summarised as the largest
connected **gaps** (centroid, area, faces), which the verdict names.

Below ``min_coverage`` (default :data:`MIN_COVERAGE`) the verdict is ``incomplete``: the part was
not seen well enough to pass or fail it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from shapeverify._lazy import cKDTree

from ..measures._grid_kernels import any_within, kernel_array
from .regions import linked_components

__all__ = ["Coverage", "compute_coverage", "seen_faces", "MIN_COVERAGE", "MAX_SAMPLES",
           "SEEN_FACE_COVERAGE"]

#: Default least covered share of the inspected area for a pass or fail verdict.  A normal
#: single view of a sheet-metal part sees 70-95 % of it; a closed part (a turned part, an
#: impeller) seen from one side at most about half, often 25-45 %: 20 % lets such views be
#: decided while a patch of a few percent, or a sparse scan, never is.  Raise it for a
#: multi-view inspection, or name the ``faces`` that must be seen.
MIN_COVERAGE = 0.2
#: Most model points used to measure the coverage.
MAX_SAMPLES = 20_000
#: ``faces="seen"``: least covered share of a face's own area for it to count as seen.  The
#: coverage radius reaches past the edge of what the scan saw, so a face next to the seen ones
#: is grazed along that edge (a strip one radius wide: a few percent of a face a few radii
#: across); a tenth keeps such faces out and every face the scan looked at in.
SEEN_FACE_COVERAGE = 0.1


@dataclass(frozen=True, eq=False)
class Coverage:
    """Coverage of the inspected CAD area by evaluated scan points.

    Attributes
    ----------
    fraction : float
        Covered share of the inspected area (0..1).
    area : float
        Inspected CAD area (mm²), estimated from the model points.
    per_face : dict {face: fraction}
    radius : float
        Coverage radius used (mm).
    points : (K, 3) float64
        The model points that represent the inspected area (model coordinates).
    face : (K,) int32
    covered : (K,) bool
    gaps : tuple of dict
        Largest uncovered connected areas first: ``{"centroid": [x, y, z], "area": mm², "faces": [...]}``.
    faces : tuple of int or None
        The inspected faces (None: all).
    """

    fraction: float
    area: float
    per_face: dict
    radius: float
    points: np.ndarray
    face: np.ndarray
    covered: np.ndarray
    gaps: tuple = ()
    faces: tuple | None = None
    min_coverage: float = MIN_COVERAGE

    @property
    def covered_area(self) -> float:
        return self.fraction * self.area

    @property
    def sufficient(self) -> bool:
        return self.fraction >= self.min_coverage

    def describe_gap(self) -> str:
        if not self.gaps:
            return ""
        from ..quantities import area_text, point_text

        g = self.gaps[0]
        return (f"the largest unseen area, {area_text(g['area'])}, is around "
                f"{point_text(g['centroid'])} on face(s) "
                f"{', '.join(str(f) for f in g['faces'][:6])}")

    def to_dict(self) -> dict:
        return {"fraction": float(self.fraction), "area_mm2": float(self.area),
                "covered_area_mm2": float(self.covered_area), "min_coverage": self.min_coverage,
                "radius_mm": float(self.radius),
                "faces": None if self.faces is None else [int(f) for f in self.faces],
                "per_face": {str(f): float(v) for f, v in self.per_face.items()},
                "gaps": [dict(g) for g in self.gaps[:10]]}

    def __repr__(self) -> str:
        return (f"Coverage(fraction={self.fraction:.3f}, area={self.area:.0f} mm², "
                f"radius={self.radius:.3g} mm, faces={len(self.per_face)}, gaps={len(self.gaps)})")


def model_samples(prep, faces=None, max_samples: int = MAX_SAMPLES):
    """Evenly spread model points of the inspected faces: ``(points (K, 3), face (K,), area_per_point)``.

    They depend only on the model and the faces, so they are kept on ``prep`` (attribute
    ``_coverage_samples``, a dict by faces) after the first inspection: about 30 ms a call less
    for a 100k-point model.
    """
    key = (None if faces is None else tuple(int(f) for f in faces), int(max_samples))
    cache = getattr(prep, "_coverage_samples", None)
    if cache is None:
        cache = {}
        try:
            prep._coverage_samples = cache
        except AttributeError:          # an object that takes no attributes: no cache
            pass
    if key not in cache:
        cache[key] = _model_samples(prep, faces, max_samples)
    return cache[key]


def _model_samples(prep, faces, max_samples):
    mp = prep.points
    pts = np.asarray(mp.points)
    face = np.asarray(mp.face, dtype=np.int32)
    if faces is not None:
        keep = np.isin(face, np.asarray(faces, dtype=np.int32))
        pts, face = pts[keep], face[keep]
    step = max(1, int(np.ceil(pts.shape[0] / max_samples)))
    pts, face = kernel_array(pts[::step]), face[::step]
    return pts, face, _area_per_point(pts, float(mp.spacing) * np.sqrt(step))


def _face_index(prep, faces, face):
    """``(faces present (F,), index of each sample's face in them (K,), samples per face (F,))``
    of the samples of :func:`model_samples` (kept beside them on ``prep``)."""
    key = ("faces", None if faces is None else tuple(int(f) for f in faces), face.shape[0])
    cache = getattr(prep, "_coverage_samples", None)
    if cache is not None and key in cache:
        return cache[key]
    fs, inv = np.unique(face, return_inverse=True)
    out = (fs, inv, np.bincount(inv, minlength=fs.size))
    if cache is not None:
        cache[key] = out
    return out


def _area_per_point(pts: np.ndarray, spacing: float, n_probe: int = 2000) -> float:
    """Surface area one of ``pts`` stands for: pi r^2 / (points within r), r = 3 spacings,
    median over an even subset of them (mm²)."""
    if pts.shape[0] < 8:
        return spacing ** 2
    r = 3.0 * spacing
    probe = pts[:: max(1, pts.shape[0] // n_probe)]
    counts = cKDTree(pts).query_ball_point(probe, r, return_length=True)
    return float(np.median(np.pi * r * r / np.maximum(counts, 1)))


def compute_coverage(prep, foot_points: np.ndarray, scan_spacing: float, *, faces=None,
                     model_size: float | None = None, min_coverage: float = MIN_COVERAGE,
                     tree: cKDTree | None = None) -> Coverage:
    """Coverage of the inspected faces by evaluated foot points (see the module docstring).

    Parameters
    ----------
    prep : shapeverify.nearest.Prepared
    foot_points : (M, 3) float64
        Foot points of the *evaluated* scan points on the CAD (model coordinates).
    scan_spacing : float
        Median spacing of those points (mm; NaN when unknown, e.g. fewer than 2 points).
    faces : sequence of int, optional
        Inspected faces (None: all).
    model_size : float, optional
        Bounding-box diagonal of the model (mm), for the radius cap.
    tree : scipy.spatial.cKDTree, optional
        Not needed any more (the covered test runs on a grid of the foot points,
        :func:`._grid_kernels.any_within`); accepted for callers that pass one.
    """
    pts, face, a_pt = model_samples(prep, faces)
    h = float(prep.spacing)
    size = float(model_size) if model_size else 500.0 * h
    s = float(scan_spacing) if np.isfinite(scan_spacing) else np.inf
    radius = max(2.0 * h, min(2.0 * s, 0.01 * size))
    if foot_points.shape[0] and pts.shape[0]:
        # "an evaluated foot point closer than r": the first one found in the grid cells
        # around a sample answers it (a nearest-neighbour query finds the nearest: 6x slower)
        covered = np.empty(pts.shape[0], bool)
        any_within(kernel_array(foot_points), pts, float(radius), covered)
    else:
        covered = np.zeros(pts.shape[0], bool)
    n = pts.shape[0]
    fraction = float(covered.mean()) if n else 0.0
    per_face = {}
    if n:
        fs, inv, tot = _face_index(prep, faces, face)
        cov = np.bincount(inv, weights=covered.astype(np.float64), minlength=fs.size)
        per_face = {int(f): float(c / t) for f, c, t in zip(fs, cov, tot)}
    gaps = _gaps(pts[~covered], face[~covered], a_pt, 2.5 * max(h, np.sqrt(a_pt)))
    return Coverage(fraction=fraction, area=n * a_pt, per_face=per_face, radius=radius,
                    points=pts, face=face, covered=covered, gaps=gaps,
                    faces=None if faces is None else tuple(int(f) for f in faces),
                    min_coverage=float(min_coverage))


def seen_faces(prep, foot_points: np.ndarray, scan_spacing: float, *,
               model_size: float | None = None,
               min_fraction: float = SEEN_FACE_COVERAGE) -> tuple[tuple | None, str]:
    """The faces the scan saw (``inspect(faces="seen")``) and the sentence that says so.

    A face is seen when at least ``min_fraction`` of its area is covered by the evaluated foot
    points (the coverage of all faces, :func:`compute_coverage`).  The inspection is then
    limited to these faces: its coverage and verdict are of them only, the rest of the part was
    not measured, which the returned sentence (a reason of the verdict) states with the share of
    the part's area they make up.

    Returns
    -------
    faces : tuple of int or None
        The seen faces, sorted; None when no face is seen that well (the whole part is then
        inspected, and the sentence says so).
    note : str
    """
    cov = compute_coverage(prep, foot_points, scan_spacing, model_size=model_size)
    faces = tuple(sorted(f for f, c in cov.per_face.items() if c >= min_fraction))
    if not faces:
        return None, (f"faces=seen: no face has {100 * min_fraction:.0f} % of its area covered "
                      "by the scan; the whole part is inspected")
    share = float(np.isin(cov.face, np.asarray(faces, dtype=cov.face.dtype)).mean())
    listed = ", ".join(str(f) for f in faces[:12]) + (f", ... ({len(faces)} faces)"
                                                       if len(faces) > 12 else "")
    plural = "s" if len(faces) != 1 else ""
    return faces, (f"inspection limited to the {len(faces)} face{plural} the scan saw (at least "
                   f"{100 * min_fraction:.0f} % of a face's area covered; {100 * share:.0f} % of "
                   f"the part's area): face{plural} {listed}; coverage and verdict are of "
                   f"{'these faces' if plural else 'it'} only, the rest of the part was not "
                   "measured")


def _gaps(pts: np.ndarray, face: np.ndarray, a_pt: float, link: float, most: int = 10) -> tuple:
    """Connected uncovered areas, largest first."""
    if pts.shape[0] == 0:
        return ()
    pairs = cKDTree(pts).query_pairs(link, output_type="ndarray")
    m = pts.shape[0]
    n_comp, labels = linked_components(m, pairs)
    sizes = np.bincount(labels, minlength=n_comp)
    out = []
    for c in np.argsort(-sizes, kind="stable")[:most]:
        sel = labels == c
        out.append({"centroid": [float(x) for x in pts[sel].mean(axis=0)],
                    "area": float(sizes[c] * a_pt),
                    "faces": [int(f) for f in np.unique(face[sel])]})
    return tuple(out)
