"""Coloured PLY of an inspection, for CloudCompare, MeshLab and similar viewers.

Each scan point (in *model* coordinates, so that it lies on the CAD model when both are loaded)
gets an RGB colour from its deviation and the deviation itself as the scalar vertex property
``deviation`` (mm; NaN where the point was not evaluated).  Colours: the diverging ColorBrewer
``RdBu_r`` scale centred at 0 (blue: material missing, red: material added), clipped at
``2 x`` the largest tolerance limit; not-evaluated points are grey.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["colored_ply", "write_colored_ply", "deviation_colors", "color_limit", "NOT_EVALUATED_RGB"]

#: Colour of points without a deviation (too far from the model, past its outer boundary).
NOT_EVALUATED_RGB = (0.6, 0.6, 0.6)
CMAP = "RdBu_r"


def check_scan_length(result, scan) -> None:
    """Raise ValueError unless ``scan`` (or None) has one row per inspected point."""
    n = result.deviations.n
    if scan is not None and len(scan) != n:
        raise ValueError(f"scan has {len(scan)} points but the inspection has {n}; pass the "
                         "scan that was inspected")


def color_limit(tolerance) -> float:
    """Half-range of the colour scale: ``2 x`` the largest |tolerance limit| (mm)."""
    return 2.0 * float(tolerance.max_abs)


def deviation_colors(values: np.ndarray, limit: float) -> np.ndarray:
    """RGB colours (N, 3) in [0, 1] for deviations: RdBu_r over ``[-limit, +limit]``, grey for NaN."""
    from matplotlib import colormaps

    values = np.asarray(values, dtype=np.float64)
    t = np.clip(0.5 + 0.5 * values / limit, 0.0, 1.0)
    rgb = colormaps[CMAP](np.nan_to_num(t, nan=0.5))[:, :3]
    rgb[~np.isfinite(values)] = NOT_EVALUATED_RGB
    return rgb


def colored_ply(result, scan=None, *, binary: bool = True) -> bytes:
    """The scan coloured by deviation, as the bytes of a PLY file.

    Parameters
    ----------
    result : InspectionResult
    scan : (N, 3) array_like, optional
        The scan as passed to ``inspect``; only its length is checked (the points written are
        ``result.deviations.points_model``, i.e. the scan in model coordinates).
    binary : bool
        Binary little-endian (default) or ASCII PLY.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        If ``scan`` does not have as many points as the inspection.
    """
    from ..io.ply import ply_bytes

    check_scan_length(result, scan)
    dev = result.deviations
    rgb = deviation_colors(dev.values, color_limit(result.tolerance))
    colors = np.rint(rgb * 255.0).astype(np.uint8)
    return ply_bytes(dev.points_model, normals=None, colors=colors,
                     scalars={"deviation": dev.values}, binary=binary)


def write_colored_ply(result, scan=None, path="deviations.ply", *, binary: bool = True) -> Path:
    """Write :func:`colored_ply` to ``path`` (str or Path); parameters and errors as there.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    path.write_bytes(colored_ply(result, scan, binary=binary))
    return path
