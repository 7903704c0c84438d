"""Synthetic phase fields with known truth, for tests and benchmarks of the unwrappers.

* :func:`smooth_field` -- a smooth surface of a given peak-to-valley phase (the benchmark field).
* :func:`fault_field` -- the smooth field plus a *fault*: a discontinuity along a line that
  starts at the left border and ends inside the image.  The step grows from 0 at the tip to
  `step` over a taper (so the field is continuous everywhere except across the fault line, and a
  path around the tip exists); where the step exceeds ``pi`` no data-only unwrapper can see it
  from a single difference, and path following across the line puts a whole region on the wrong
  fringe.  The wrapped-phase residue sits where the step crosses ``pi``.

Both return the noise-free truth and, with ``sigma > 0``, the wrapped phase with Gaussian phase
noise of standard deviation `sigma` (radians), drawn from a seeded generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._random import generator
from .wrap import wrap

__all__ = ["smooth_field", "fault_field", "PhaseField", "wrong_fraction"]


@dataclass(frozen=True, repr=False)
class PhaseField:
    """A synthetic test field.

    Attributes
    ----------
    true : (H, W) float64
        Noise-free unwrapped phase (radians).
    psi : (H, W) float64
        Wrapped phase with noise, in ``(-pi, pi]``.
    fault : (H, W) bool
        True on the pixels just below the fault line where the step exceeds ``pi`` (empty for a
        smooth field); for plots and diagnostics.
    sigma : float
        Phase-noise standard deviation (radians).
    """

    true: np.ndarray
    psi: np.ndarray
    fault: np.ndarray
    sigma: float

    def __repr__(self):
        return (f"PhaseField(shape={self.true.shape}, sigma={self.sigma:g}, "
                f"fault_pixels={int(self.fault.sum())})")


def _check(n, sigma):
    if isinstance(n, (int, np.integer)):
        h = w = int(n)
    else:
        h, w = (int(v) for v in n)
    if h < 8 or w < 8:
        raise ValueError(f"field size must be at least 8 x 8, got {(h, w)}")
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be finite and >= 0 (radians), got {sigma!r}")
    return h, w


def _surface(h, w, peak_to_valley):
    y, x = np.mgrid[0:h, 0:w]
    y = y / h
    x = x / w
    f = (30.0 * np.exp(-((x - 0.45) ** 2 + (y - 0.55) ** 2) / 0.1)
         + 8.0 * x * y + 3.0 * np.sin(4.0 * x) * np.cos(3.0 * y))
    f -= f.min()
    return f * (peak_to_valley / f.max())


def _noisy(true, sigma, rng):
    g = generator(rng)
    return wrap(true + sigma * g.standard_normal(true.shape)) if sigma > 0 else wrap(true)


def smooth_field(n=1024, sigma: float = 0.0, peak_to_valley: float = 40.0, rng=12345) -> PhaseField:
    """Smooth test surface (a Gaussian bump, a saddle and a wave), wrapped, with phase noise.

    Parameters
    ----------
    n : int or (H, W)
        Size in pixels.
    sigma : float >= 0
        Standard deviation of the Gaussian phase noise added before wrapping (radians).
    peak_to_valley : float
        Phase range of the truth (radians).
    rng : int or numpy Generator
        Seed of the noise (fixed default: identical every run).

    Returns
    -------
    PhaseField
    """
    h, w = _check(n, sigma)
    true = _surface(h, w, float(peak_to_valley))
    return PhaseField(true=true, psi=_noisy(true, sigma, rng), fault=np.zeros((h, w), bool),
                      sigma=float(sigma))


def fault_field(n=1024, step: float = 1.5 * np.pi, sigma: float = 0.0, tip=(0.55, 0.65),
                start_row: float = 0.40, taper: float = 0.15, peak_to_valley: float = 40.0,
                rng=12345) -> PhaseField:
    """Smooth field plus a fault: a step along a line from the left border to a tip inside.

    Parameters
    ----------
    n : int or (H, W)
        Size in pixels.
    step : float
        Largest step across the fault (radians), reached at the border; values between ``pi``
        and ``2*pi`` are the hard case (the wrapped difference across the fault is
        ``step - 2*pi``, indistinguishable from a smooth slope of the opposite sign).
    sigma : float >= 0
        Phase noise (radians) added before wrapping.
    tip : (row, col) fractions of (H, W)
        End of the fault inside the image.
    start_row : float
        Row (fraction of H) where the fault meets the left border.
    taper : float
        Length (fraction of W) over which the step grows from 0 at the tip to `step`.
    peak_to_valley : float
        Phase range of the smooth part (radians).
    rng : int or numpy Generator
        Seed of the noise.

    Returns
    -------
    PhaseField
        ``true`` is the smooth field plus ``s(x)`` on the pixels below the fault line, with
        ``s`` rising linearly from 0 at the tip's column to `step` a `taper` further left.

    Examples
    --------
    >>> f = fault_field(64, sigma=0.0)
    >>> bool(np.abs(np.diff(f.true, axis=0)).max() > np.pi)   # a step of more than pi
    True
    """
    h, w = _check(n, sigma)
    tr, tc = float(tip[0]) * h, float(tip[1]) * w
    if not (0 < tc < w - 1 and 0 < tr < h - 1):
        raise ValueError(f"tip must lie inside the image (fractions in (0, 1)), got {tip!r}")
    if not 0 < taper:
        raise ValueError(f"taper must be > 0, got {taper!r}")
    r0 = float(start_row) * (h - 1)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    line = r0 + (tr - r0) * x / tc                      # fault row at column x
    s = float(step) * np.clip((tc - x) / (taper * w), 0.0, 1.0)
    below = y > line
    true = _surface(h, w, float(peak_to_valley)) + np.where(below, s, 0.0)
    above_line = np.vstack([np.zeros((1, w), bool), ~below[:-1]])
    fault = below & above_line & (s > np.pi)
    return PhaseField(true=true, psi=_noisy(true, sigma, rng), fault=fault, sigma=float(sigma))


def wrong_fraction(phi, true, mask=None) -> float:
    """Fraction of pixels on the wrong fringe after removing the global ``2*pi*k`` offset.

    ``k = round((phi - true) / (2*pi))`` per pixel; the most common ``k`` is the offset, every
    other pixel (and every NaN of `phi` inside `mask`) counts as wrong.

    Parameters
    ----------
    phi, true : (H, W) float arrays
    mask : (H, W) bool or None
        Pixels to count (default: all).
    """
    d = np.asarray(phi, np.float64) - np.asarray(true, np.float64)
    if mask is not None:
        d = d[np.asarray(mask, bool)]
    d = d.ravel()
    k = np.round(d / (2 * np.pi))
    ok = np.isfinite(k)
    if not ok.any():
        return 1.0
    _, counts = np.unique(k[ok], return_counts=True)
    return 1.0 - counts.max() / d.size
