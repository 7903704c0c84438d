"""Phase unwrapping for optical shape measurement (thesis Ch. 3-4, Paper V).

>>> import numpy as np
>>> from shapeverify import phase
>>> y, x = np.mgrid[0:64, 0:64]
>>> true = 0.02 * ((x - 30.0) ** 2 + (y - 20.0) ** 2)           # up to 70 rad: many fringes
>>> psi = np.angle(np.exp(1j * true))                           # wrapped into (-pi, pi]
>>> phi = phase.unwrap(psi, method="auto", mask=None, quality=None, reference=None)
>>> float(np.abs(phi - phi[20, 30] - (true - true[20, 30])).max()) < 1e-9
True

Wrapping conventions, masks (True = valid) and congruence: see :mod:`shapeverify.phase.wrap`.
Methods (``method=``):

=============  ==========================================================================
``"auto"``     residue-aware minimum-cost-flow L1 (Costantini 1998) on the complex-smoothed
               map, costs from the steps seen across each edge, congruent with the data
               (robust to noise and to faults longer than pi that end inside the image;
               exact on clean data) -- :func:`unwrap_mcf` (also ``"mcf"``)
``"filtered"`` complex-domain smoothing + reliability sorting + congruence (the default
               before; fast, but crosses faults) -- :func:`unwrap_filtered`
``"quality"``  reliability-sorting path following (Herráez 2002) -- :func:`unwrap_quality`
``"ls"``       unweighted least squares by DCT (Ghiglia & Romero 1994) -- :func:`unwrap_ls`
``"wls"``      weighted least squares, DCT-preconditioned CG -- :func:`unwrap_wls`
``"lp"``       minimum Lp-norm (default p = 0) by IRLS -- :func:`unwrap_lp`
``"nearest"``  only with a reference: ``reference + W(psi - reference)`` pixel-wise
=============  ==========================================================================

With ``reference=`` (a predicted unwrapped phase, e.g. from the CAD model) the method is
applied to ``W(psi - reference)`` and steps larger than ``pi`` are recovered
(:func:`unwrap_with_reference`; the predict-unwrap-register loop is :func:`iterate_unwrap`,
wired to the camera and registration modules for a CAD model in :func:`unwrap_with_cad`).
"""

from __future__ import annotations

from .cad_unwrap import HolographySetup, predict_phase, unwrap_with_cad
from .fringes import PhaseShift, fringe_images, phase_shift, temporal_unwrap
from shapeverify.camera.fringe_analysis import FringeAnalysis, find_carrier, ftp, wff
from .holography import (depth_per_fringe, phase_difference, phase_to_depth, phase_to_points,
                         points_to_phase, synthetic_wavelength)
from .files import plot_unwrap, read_mask, read_phase, unwrap_file
from .fields import fault_field, smooth_field
from .minimum_norm import solve_poisson_dct, unwrap_lp, unwrap_ls, unwrap_wls
from .hologram import (HologramDepth, Reconstruction, angular_spectrum, dual_wavelength_depth,
                       reconstruct)
from .network_flow import unwrap_mcf
from .sum_of_norms import SumOfNormsUnwrap, unwrap_sum_of_norms
from .path_following import pseudo_correlation, unwrap_filtered, unwrap_quality
from .regularised import (DATA_METHODS, IterativeUnwrap, ReferenceUnwrap, UnwrapStop,
                          iterate_unwrap, unwrap_data, unwrap_with_reference)
from .wrap import residues, unwrap_1d, wrap

METHODS = tuple(DATA_METHODS) + ("nearest",)

__all__ = [
    "Reconstruction", "UnwrapStop",
    "wrap", "unwrap", "unwrap_1d", "residues", "pseudo_correlation", "METHODS",
    "unwrap_quality", "unwrap_filtered", "unwrap_mcf", "unwrap_ls", "unwrap_wls", "unwrap_lp",
    "fault_field", "smooth_field", "unwrap_sum_of_norms", "SumOfNormsUnwrap",
    "reconstruct", "angular_spectrum", "dual_wavelength_depth", "HologramDepth",
    "solve_poisson_dct", "unwrap_with_reference", "ReferenceUnwrap", "iterate_unwrap",
    "IterativeUnwrap", "HolographySetup", "predict_phase", "unwrap_with_cad",
    "synthetic_wavelength", "depth_per_fringe", "phase_difference", "phase_to_depth",
    "phase_to_points", "points_to_phase",
    "phase_shift", "PhaseShift", "fringe_images", "temporal_unwrap",
    "ftp", "wff", "FringeAnalysis", "find_carrier",
    "read_phase", "read_mask", "plot_unwrap", "unwrap_file",
]


def unwrap(psi, method="auto", mask=None, quality=None, reference=None):
    """Unwrap a 2-D wrapped phase map.

    Parameters
    ----------
    psi : (H, W) array_like of float
        Wrapped phase in radians (values modulo ``2*pi`` are what matter).
    method : str
        One of :data:`METHODS` (see the module docstring).  ``"auto"`` is the robust default.
    mask : (H, W) bool or None
        True where the phase is valid.  ``None``: NaN pixels are treated as masked.  With an
        explicit mask, NaN at a pixel the mask calls valid is an error.
    quality : (H, W) array_like of float or None
        Pixel quality, higher = better (e.g. fringe modulation): scales the cut costs of
        ``"auto"``/``"mcf"`` (cuts prefer poor pixels) and weights the ``"wls"``/``"lp"``
        methods (scaled to max 1, must be >= 0 there); orders the path of the path-following
        methods (``"filtered"``, ``"quality"``); not accepted by ``"ls"``.
    reference : (H, W) array_like of float or None
        Predicted unwrapped phase (e.g. rendered from the CAD model at its approximate pose)
        that regularises the result: see :func:`unwrap_with_reference`.

    Returns
    -------
    phi : (H, W) float64
        Unwrapped phase, congruent with `psi` (``phi - psi`` a multiple of ``2*pi``), NaN
        outside the mask.  Without a reference each 4-connected region's ``2*pi*k`` offset is
        arbitrary; with one, it is the one closest to the reference.

    Raises
    ------
    ValueError
        `psi` not 2-D or smaller than 2 x 2; infinite values; NaN inside an explicit mask;
        mask, quality or reference of the wrong shape; reference not finite on a valid pixel;
        no valid pixel; unknown method, or ``"nearest"`` without a reference.

    References
    ----------
    Bergström (2011), thesis Ch. 4; Herráez et al. (2002); Ghiglia & Romero (1994);
    Ghiglia & Pritt (1998); Paper V.

    Examples
    --------
    >>> import numpy as np
    >>> y, x = np.mgrid[0:64, 0:80]
    >>> true = 0.004 * (x - 40.0) ** 2 + 0.15 * y
    >>> phi = unwrap(wrap(true))
    >>> k = np.round((phi - true) / (2 * np.pi))
    >>> bool(np.allclose(phi, true + 2 * np.pi * k[0, 0]))
    True
    """
    if reference is not None:
        return unwrap_with_reference(psi, reference, mask=mask, quality=quality,
                                     method=method).phase
    return unwrap_data(psi, method=method, mask=mask, quality=quality)
