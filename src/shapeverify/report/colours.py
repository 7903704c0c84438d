"""The deviation colour map of every report (HTML 3D view, PNG summary, coloured PLY).

One scale for all of them: the diverging ColorBrewer ``RdBu_r`` map centred at 0 (blue: material
missing, red: material added), clipped at ``2 x`` the largest tolerance limit
(:func:`color_limit`); points without a deviation (too far from the model, past its outer
boundary) are grey (:data:`NOT_EVALUATED_RGB`).  The PDF report draws 7 bands instead
(:data:`BAND_COLOURS`).  Change the colours here.

Example
-------
>>> import numpy as np
>>> deviation_colors(np.array([0.0, np.nan]), 0.4).round(3).tolist()   # 0: the scale's white middle
[[0.969, 0.966, 0.965], [0.6, 0.6, 0.6]]
"""

from __future__ import annotations

import numpy as np

__all__ = ["CMAP", "NOT_EVALUATED_RGB", "BAND_COLOURS", "color_limit", "deviation_colors"]

#: The matplotlib / plotly name of the diverging colour map.
CMAP = "RdBu_r"
#: Colour of points without a deviation (too far from the model, past its outer boundary).
NOT_EVALUATED_RGB = (0.6, 0.6, 0.6)
#: The PDF report's deviation bands (:mod:`shapeverify.characteristics.pdf`: 7 bands at
#: ``b * [-2, -1, -0.5, 0.5, 1, 2]``), from most negative to most positive.
BAND_COLOURS = ("#5b2a86", "#2166ac", "#67c5e0", "#3a9e4f", "#f2d43d", "#f08a24", "#b3261e")


def color_limit(tolerance) -> float:
    """Half-range of the colour scale: ``2 x`` the largest |tolerance limit| (mm)."""
    return 2.0 * float(tolerance.max_abs)


def deviation_colors(values: np.ndarray, limit: float) -> np.ndarray:
    """RGB colours (N, 3) in [0, 1] for deviations: RdBu_r over ``[-limit, +limit]``, grey for NaN.

    Parameters
    ----------
    values : (N,) float64
        Signed deviations (mm); NaN where not evaluated.
    limit : float > 0
        Deviation (mm) at the ends of the scale (:func:`color_limit`).
    """
    from matplotlib import colormaps

    values = np.asarray(values, dtype=np.float64)
    t = np.clip(0.5 + 0.5 * values / limit, 0.0, 1.0)
    rgb = colormaps[CMAP](np.nan_to_num(t, nan=0.5))[:, :3]
    rgb[~np.isfinite(values)] = NOT_EVALUATED_RGB
    return rgb
