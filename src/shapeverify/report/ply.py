"""Coloured PLY of an inspection, for CloudCompare, MeshLab and similar viewers.

Each scan point (in *model* coordinates, so that it lies on the CAD model when both are loaded)
gets an RGB colour from its deviation and the deviation itself as the scalar vertex property
``deviation`` (mm; NaN where the point was not evaluated).  Colours: the reports' one colour map
(:mod:`shapeverify.report.colours`: ``RdBu_r`` centred at 0, clipped at ``2 x`` the largest
tolerance limit; not-evaluated points grey).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .colours import NOT_EVALUATED_RGB, color_limit, deviation_colors  # noqa: F401  (also importable from here)

__all__ = ["colored_ply", "write_colored_ply", "deviation_colors", "color_limit", "NOT_EVALUATED_RGB"]


def check_scan_length(result, scan) -> None:
    """Raise ValueError unless ``scan`` (or None) has one row per inspected point."""
    n = result.deviations.n
    if scan is not None and len(scan) != n:
        raise ValueError(f"scan has {len(scan)} points but the inspection has {n}; pass the "
                         "scan that was inspected")


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
