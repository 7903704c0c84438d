"""Fitting: NURBS curves and surfaces by orthogonal distance, and least-squares geometric elements.

>>> from shapeverify import fitting
>>> import numpy as np
>>> t = np.linspace(0, np.pi, 50)
>>> fitting.fit_circle(np.column_stack([np.cos(t), np.sin(t)])).radius
1.0

Curves and surfaces (Papers VI-VII): :func:`fit_curve`, :func:`fit_surface` with
``method="fixed" | "odr" | "varpro"``; knot and parameter helpers.  Elements (ASME B89.4.10
style, robust losses by IRLS): :func:`fit_line`, :func:`fit_plane`, :func:`fit_circle`,
:func:`fit_sphere`, :func:`fit_cylinder`, :func:`fit_cone`.  Files: :func:`fit_points_file`.
"""

from .curves import (CurveFit, FitSolver, approximation_knots, chord_length_params, fit_curve,
                     project_to_curve, uniform_knots)
from .elements import (LOSSES, CircleFit, ConeFit, CylinderFit, LineFit, PlaneFit, SphereFit,
                       fit_circle, fit_cone, fit_cylinder, fit_line, fit_plane, fit_sphere,
                       robust_weights)
from .export import fit_points_file, nurbs_from_dict, nurbs_to_dict
from .surfaces import SurfaceFit, fit_surface, project_to_surface, surface_params

__all__ = [
    "FitSolver",
    "fit_curve", "fit_surface", "CurveFit", "SurfaceFit",
    "chord_length_params", "approximation_knots", "uniform_knots", "surface_params",
    "project_to_curve", "project_to_surface",
    "fit_line", "fit_plane", "fit_circle", "fit_sphere", "fit_cylinder", "fit_cone",
    "LineFit", "PlaneFit", "CircleFit", "SphereFit", "CylinderFit", "ConeFit",
    "robust_weights", "LOSSES",
    "fit_points_file", "nurbs_to_dict", "nurbs_from_dict",
]
