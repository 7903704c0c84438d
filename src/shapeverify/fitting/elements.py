"""Least-squares geometric elements: line, plane, circle, sphere, cylinder, cone.

Every fit minimises the sum of squared *orthogonal* (geometric) distances from the points to
the element, as in ASME B89.4.10 / the NIST Algorithm Testing System.  Lines and planes have
closed-form solutions (principal axes of the centred points); circles, spheres, cylinders and
cones are solved by Levenberg-Marquardt on the geometric distances, started from an algebraic
fit (Pratt's circle/sphere fit, principal axes for the direction of a cylinder or cone).

Robust variants: ``loss="huber" | "tukey" | "cauchy" | "welsch"`` solves the M-estimation
problem by iteratively reweighted least squares (IRLS).  The residual scale is the MAD,
``1.4826 * median(|r|)``, re-estimated in every reweighting step unless ``scale`` is given;
the tuning constants give 95 % asymptotic efficiency at the normal distribution
(Huber 1.345, Tukey 4.685, Cauchy 2.385, Welsch 2.985).  Redescending losses (Tukey, Welsch,
Cauchy) start from a few Huber steps so that gross outliers cannot capture the start.

Units: those of the points (millimetres in this project).

The fits live in :mod:`.lines_planes`, :mod:`.spheres_circles` and :mod:`.cylinders_cones`;
the shared IRLS / Levenberg-Marquardt machinery in :mod:`._element_base`.  This module
re-exports the public names.

References
----------
ASME B89.4.10-2000; NIST Algorithm Testing System (reference data in ``../shared/data/fitting/nist``).
V. Pratt, "Direct least-squares fitting of algebraic surfaces", SIGGRAPH 1987.
A. Forbes, "Least-squares best-fit geometric elements", NPL report DITC 140/89, 1989.
P. W. Holland and R. E. Welsch, "Robust regression using iteratively reweighted least-squares", 1977.
"""

from __future__ import annotations

from ._element_base import LOSSES, robust_weights
from .cylinders_cones import ConeFit, CylinderFit, fit_cone, fit_cylinder
from .lines_planes import LineFit, PlaneFit, fit_line, fit_plane
from .spheres_circles import CircleFit, SphereFit, fit_circle, fit_sphere

__all__ = [
    "LineFit", "PlaneFit", "CircleFit", "SphereFit", "CylinderFit", "ConeFit",
    "fit_line", "fit_plane", "fit_circle", "fit_sphere", "fit_cylinder", "fit_cone",
    "robust_weights", "LOSSES",
]
