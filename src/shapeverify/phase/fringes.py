"""Projected fringes (thesis Ch. 3.1): N-step phase shifting and temporal (hierarchical) unwrapping.

Intensity model: the n-th image of a phase-shifting sequence is

    I_n = A + B * cos(phi + delta_n),      delta_n = 2*pi*n / N by default,

with background ``A``, modulation ``B`` (the fringe contrast, a natural quality map: low in
shadows, on dark or specular spots) and the wanted phase ``phi``.  Note the sign: a shift
*added* to the phase.  Sequences recorded as ``cos(phi - delta_n)`` give ``-phi``; negate the
result or pass ``shifts=-delta``.

References
----------
Bergström (2011), thesis Ch. 3.1 (projected fringes) and Paper III.
J. H. Bruning et al., Appl. Opt. 13 (1974) 2693 (synchronous detection / N-step formula);
J. M. Huntley, H. Saldner, Appl. Opt. 32 (1993) 3047 (temporal phase unwrapping);
C. Zuo et al., Opt. Lasers Eng. 85 (2016) 84-103 (review: hierarchical multi-frequency
temporal unwrapping).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .wrap import TWO_PI, wrap

__all__ = ["PhaseShift", "phase_shift", "fringe_images", "temporal_unwrap"]


@dataclass(frozen=True, repr=False)
class PhaseShift:
    """Result of :func:`phase_shift`.

    Attributes
    ----------
    phase : (H, W) float64
        Wrapped phase in ``(-pi, pi]``.
    modulation : (H, W) float64
        Fringe amplitude ``B`` (>= 0), in image intensity units.
    background : (H, W) float64
        Mean intensity ``A``.
    """

    phase: np.ndarray
    modulation: np.ndarray
    background: np.ndarray

    def __repr__(self):
        return (f"PhaseShift(shape={self.phase.shape}, "
                f"median modulation={float(np.nanmedian(self.modulation)):.4g})")


def _shifts(n, shifts):
    if shifts is None:
        return TWO_PI * np.arange(n) / n
    d = np.asarray(shifts, dtype=np.float64)
    if d.shape != (n,) or not np.all(np.isfinite(d)):
        raise ValueError(f"shifts must be a finite ({n},) array (one per image), got shape {d.shape}")
    return d


def phase_shift(images, shifts=None) -> PhaseShift:
    """Wrapped phase, modulation and background from N phase-shifted fringe images.

    Solves ``I_n = A + a cos(delta_n) - b sin(delta_n)`` (``a = B cos phi``, ``b = B sin phi``)
    in the least-squares sense per pixel; for equal shifts ``delta_n = 2*pi*n/N`` this is the
    classical N-step formula ``phi = atan2(-sum I_n sin delta_n, sum I_n cos delta_n)``,
    ``B = (2/N) |sum I_n exp(-i delta_n)|``.

    Parameters
    ----------
    images : (N, H, W) array_like of float, N >= 3
        The phase-shifted images (N >= 3 shifts that are not all equal modulo pi).
    shifts : (N,) array_like or None
        Phase shifts in radians; ``None``: ``2*pi*n/N``.

    Returns
    -------
    PhaseShift

    Raises
    ------
    ValueError
        Fewer than 3 images, not 3-D, non-finite values, or shifts that leave the system
        singular.

    Examples
    --------
    >>> phi = np.linspace(-3.0, 3.0, 12).reshape(3, 4)
    >>> r = phase_shift(fringe_images(phi, steps=4))
    >>> bool(np.allclose(r.phase, phi)), bool(np.allclose(r.modulation, 0.5))
    (True, True)
    """
    I = np.asarray(images, dtype=np.float64)
    if I.ndim != 3:
        raise ValueError(f"images must be a stack of shape (N, H, W), got shape {I.shape}")
    n = I.shape[0]
    if n < 3:
        raise ValueError(f"phase shifting needs at least 3 images, got {n}")
    if not np.all(np.isfinite(I)):
        raise ValueError("images hold NaN/inf values")
    d = _shifts(n, shifts)
    M = np.stack([np.ones(n), np.cos(d), -np.sin(d)], axis=1)  # (N, 3)
    if np.linalg.matrix_rank(M) < 3:
        raise ValueError("the phase shifts do not determine the phase (need >= 3 distinct shifts "
                         "modulo pi)")
    coef = np.linalg.pinv(M)  # (3, N)
    A, a, b = np.tensordot(coef, I, axes=(1, 0))
    return PhaseShift(phase=wrap(np.arctan2(b, a)), modulation=np.hypot(a, b), background=A)


def fringe_images(phi, steps: int = 4, background: float = 0.5, modulation: float = 0.5,
                  shifts=None):
    """Synthetic phase-shifted fringe images ``A + B cos(phi + delta_n)`` (for tests/simulation).

    Parameters
    ----------
    phi : (H, W) array_like
        Phase (radians).
    steps : int >= 3
        Number of images (ignored if `shifts` is given).
    background, modulation : float or (H, W)
        ``A`` and ``B``.
    shifts : (N,) array_like or None
        Shifts; ``None``: ``2*pi*n/steps``.

    Returns
    -------
    images : (N, H, W) float64
    """
    p = np.asarray(phi, dtype=np.float64)
    n = int(steps) if shifts is None else len(shifts)
    d = _shifts(n, shifts)
    return np.asarray(background) + np.asarray(modulation) * np.cos(p[None] + d[:, None, None])


def temporal_unwrap(phases, frequencies):
    """Hierarchical temporal unwrapping from phases measured at several fringe frequencies.

    The lowest frequency must be unambiguous on its own (at most one fringe across the field,
    so that its wrapped phase *is* its unwrapped phase); each finer phase is then unwrapped
    with the previous level scaled to its frequency:

        phi_k = psi_k + 2*pi * round((phi_{k-1} * f_k / f_{k-1} - psi_k) / (2*pi)).

    This is exact while the error of the scaled coarser phase stays below ``pi``, i.e. while
    ``phase noise * f_k / f_{k-1} < pi``; keep the frequency ratios modest (4-8) with noisy data.
    Pixels are independent: no spatial path, so discontinuities and isolated regions are no
    problem.

    Parameters
    ----------
    phases : sequence of (H, W) array_like, or (K, H, W)
        Wrapped phases, one per frequency, coarsest first.  NaN pixels stay NaN.
    frequencies : (K,) array_like of float > 0, increasing
        Fringe frequencies (fringes across the field, or any proportional quantity).

    Returns
    -------
    phi : (H, W) float64
        Unwrapped phase at the finest (last) frequency.

    Raises
    ------
    ValueError
        Fewer than 2 levels, shape mismatch, frequencies not positive and increasing.

    References
    ----------
    Huntley & Saldner (1993); Zuo et al. (2016), Sec. 4 (hierarchical approach).

    Examples
    --------
    >>> x = np.linspace(0.0, 1.0, 200)[None, :] * np.ones((3, 1))
    >>> f = [1, 8, 64]
    >>> theta = 6.2 * x - 3.1              # the coarsest phase: inside one period (-pi, pi]
    >>> psis = [wrap(fk * theta) for fk in f]
    >>> bool(np.allclose(temporal_unwrap(psis, f), 64 * theta))
    True
    """
    P = np.asarray(phases, dtype=np.float64)
    if P.ndim != 3 or P.shape[0] < 2:
        raise ValueError(f"phases must be K >= 2 maps of shape (H, W), got array shape {P.shape}")
    f = np.asarray(frequencies, dtype=np.float64)
    if f.shape != (P.shape[0],):
        raise ValueError(f"need one frequency per phase map: {P.shape[0]} maps, frequencies shape {f.shape}")
    if not (np.all(np.isfinite(f)) and np.all(f > 0) and np.all(np.diff(f) > 0)):
        raise ValueError(f"frequencies must be positive and increasing, got {f.tolist()}")
    if np.isinf(P).any():
        raise ValueError("phases hold infinite values")
    phi = P[0].copy()
    for k in range(1, P.shape[0]):
        scaled = phi * (f[k] / f[k - 1])
        phi = P[k] + TWO_PI * np.rint((scaled - P[k]) / TWO_PI)
    return phi
