"""Reading phase maps and masks, the figure of an unwrapping, and the file-to-file entry point.

Scale conventions of :func:`read_phase`
---------------------------------------
* Floating-point data (``.npy`` of float dtype, 32-bit float TIFF): radians, taken as they are
  (any period offset: ``[-pi, pi)``, ``[0, 2*pi)``, ... all work; NaN = no measurement).
* Unsigned 8- or 16-bit integer data (8-bit grey PNG/TIFF, 16-bit grey PNG/TIFF, ``.npy`` of
  ``uint8``/``uint16``): a quantised wrapped phase, ``psi = 2*pi * v / 2**bits - pi``, so 0 is
  ``-pi`` and the full range covers one period without repeating ``pi``.
* Anything else (signed or 32-bit integers, booleans, complex, palette images, colour images
  whose channels differ) raises ``ValueError``: there is no safe guess of its scale.
* RGB(A) images whose colour channels are equal are read as grey (alpha ignored).

Limits of the TIFF reader (Pillow; ``tifffile`` is not a dependency): single-page grey TIFFs in
the modes Pillow decodes (8/16-bit unsigned, 32-bit float); multi-page stacks, 64-bit float and
most scientific TIFF variants are refused with an error -- save such data as ``.npy``.

Masks (:func:`read_mask`): any of the formats above; a pixel is valid where the value is
non-zero (and not NaN).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from .wrap import TWO_PI, residues

log = logging.getLogger(__name__)

__all__ = ["read_phase", "read_mask", "plot_unwrap", "unwrap_file"]

_IMAGE_SUFFIXES = {".png", ".tif", ".tiff"}


def _read_raw(path):
    """Array as stored (npy) or as decoded by Pillow (png/tif), grey only."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"no such file: {p}")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        from shapeverify.io.npy import load_npy

        data = p.read_bytes()
        if not data.startswith(b"\x93NUMPY"):
            raise ValueError(f"{p.name} is not a readable .npy array (no .npy header: the file "
                             "is something else); save the phase map with numpy.save as a 2-D "
                             "float array")
        # the header is checked against the file size before anything is allocated
        return load_npy(data, p.name, error=ValueError)
    if suffix not in _IMAGE_SUFFIXES:
        raise ValueError(f"unsupported phase file type {suffix!r} ({p.name}); use .npy, .png or .tif")
    from PIL import Image  # Pillow comes with matplotlib

    from shapeverify.io.image_header import check_image_size

    check_image_size(p, what="phase map")   # the size its header declares, before decoding

    try:
        im = Image.open(p)
    except Exception as exc:  # Pillow raises various types for undecodable files
        raise ValueError(f"cannot read {p.name} with Pillow ({exc}); save the data as .npy") from exc
    with im:
        if getattr(im, "n_frames", 1) > 1:
            raise ValueError(f"{p.name} has {im.n_frames} pages; only single-page images are "
                             "supported (save a stack as .npy and pass one map at a time)")
        mode = im.mode
        try:
            a = np.array(im)
        except Exception as exc:
            raise ValueError(f"Pillow cannot decode {p.name} (mode {mode}): {exc}; "
                             "save the data as .npy") from exc
    if mode in ("RGB", "RGBA"):
        c = a[..., :3]
        if not (np.array_equal(c[..., 0], c[..., 1]) and np.array_equal(c[..., 0], c[..., 2])):
            raise ValueError(f"{p.name} is a colour image; a phase map must be grey "
                             "(8/16-bit unsigned or 32-bit float)")
        a = c[..., 0]
    elif mode == "LA":
        a = a[..., 0]
    elif mode in ("P", "PA", "1", "CMYK", "YCbCr", "HSV", "LAB"):
        raise ValueError(f"{p.name}: image mode {mode!r} has no phase scale; "
                         "use 8/16-bit grey or 32-bit float")
    return a


def read_phase(path):
    """Read a wrapped phase map (radians) from ``.npy``, ``.png`` or ``.tif``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    psi : (H, W) float64, radians (see the module notes for the scale conventions).

    Raises
    ------
    ValueError
        Missing file, unsupported type or mode, not 2-D, or a dtype without a defined scale.
    """
    a = _read_raw(path)
    name = Path(path).name
    if a.ndim != 2:
        raise ValueError(f"{name}: a phase map must be 2-D, got shape {a.shape}")
    if a.dtype.kind == "f":
        return a.astype(np.float64)
    if a.dtype in (np.uint8, np.uint16):
        bits = 8 * a.dtype.itemsize
        return a.astype(np.float64) * (TWO_PI / 2.0 ** bits) - np.pi
    raise ValueError(f"{name}: dtype {a.dtype} has no defined phase scale; use float radians or "
                     "uint8/uint16 quantised phase (0 = -pi, full range = 2*pi)")


def read_mask(path, shape=None):
    """Read a validity mask: True where the stored value is non-zero (and not NaN).

    Parameters
    ----------
    path : str or Path (.npy, .png, .tif)
    shape : tuple or None
        Expected (H, W); a mismatch raises ValueError.

    Returns
    -------
    mask : (H, W) bool
    """
    a = _read_raw(path)
    name = Path(path).name
    if a.ndim != 2:
        raise ValueError(f"{name}: a mask must be 2-D, got shape {a.shape}")
    if a.dtype.kind not in "biuf":
        raise ValueError(f"{name}: mask dtype {a.dtype} is not boolean or numeric")
    m = np.asarray(a != 0) & ~np.isnan(a.astype(np.float64))
    if shape is not None and m.shape != tuple(shape):
        raise ValueError(f"mask {name} has shape {m.shape}, the phase map {tuple(shape)}")
    return m


def plot_unwrap(psi, phi, path, title=None):
    """Save a two-panel figure: wrapped phase and unwrapped phase (masked pixels blank).

    Parameters
    ----------
    psi, phi : (H, W) array_like
        Wrapped and unwrapped phase (NaN = masked).
    path : str or Path
        Output image (format from the suffix, e.g. ``.png``).
    title : str or None

    Returns
    -------
    Path of the written file.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    a = np.asarray(psi, dtype=np.float64)
    b = np.asarray(phi, dtype=np.float64)
    if a.ndim != 2 or a.shape != b.shape:
        raise ValueError(f"psi and phi must be 2-D of the same shape, got {a.shape} and {b.shape}")
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    im1 = ax1.imshow(np.where(np.isnan(b), np.nan, a), cmap="twilight", vmin=-np.pi, vmax=np.pi,
                     interpolation="nearest")
    ax1.set_title("wrapped phase (rad)")
    fig.colorbar(im1, ax=ax1, shrink=0.85)
    im2 = ax2.imshow(b, cmap="viridis", interpolation="nearest")
    ax2.set_title("unwrapped phase (rad)")
    fig.colorbar(im2, ax=ax2, shrink=0.85)
    for ax in (ax1, ax2):
        ax.set_xlabel("column")
        ax.set_ylabel("row")
    if title:
        fig.suptitle(title)
    out = Path(path)
    fig.savefig(out, dpi=100)
    return out


def unwrap_file(in_path, out_path, method="auto", mask_path=None, plot_path=None) -> dict:
    """Read a wrapped phase file, unwrap it, save ``.npy`` (NaN = masked); the CLI's worker.

    Parameters
    ----------
    in_path : str or Path
        ``.npy``, ``.png`` or ``.tif`` (scale conventions: :func:`read_phase`).
    out_path : str or Path
        Output ``.npy`` file (float64 radians, NaN outside the mask).
    method : str
        As :func:`shapeverify.phase.unwrap`.
    mask_path : str or Path or None
        Mask file (non-zero = valid).  Without it, NaN pixels of the input are masked.
    plot_path : str or Path or None
        If given, a figure of the wrapped and unwrapped phase (:func:`plot_unwrap`).

    Returns
    -------
    dict with ``input``, ``output``, ``plot``, ``method``, ``shape``, ``valid_pixels``,
    ``masked_pixels``, ``residues``, ``phase_min``, ``phase_max``, ``fringes`` (phase range /
    2 pi), ``seconds`` -- JSON-serialisable.

    Raises
    ------
    ValueError
        Bad files or input (messages from :func:`read_phase`, :func:`read_mask`,
        :func:`shapeverify.phase.unwrap`), or an output path not ending in ``.npy``.
    """
    from . import unwrap

    out = Path(out_path)
    if out.suffix.lower() != ".npy":
        raise ValueError(f"output must be a .npy file, got {out.name!r}")
    psi = read_phase(in_path)
    mask = None if mask_path is None else read_mask(mask_path, psi.shape)
    t0 = time.perf_counter()
    phi = unwrap(psi, method=method, mask=mask)
    seconds = time.perf_counter() - t0
    np.save(out, phi)
    valid = np.isfinite(phi)
    plot = None
    if plot_path is not None:
        plot = str(plot_unwrap(psi, phi, plot_path, title=f"{Path(in_path).name} ({method})"))
    lo = float(np.nanmin(phi))
    hi = float(np.nanmax(phi))
    return {
        "input": str(in_path),
        "output": str(out),
        "plot": plot,
        "method": method,
        "shape": [int(s) for s in psi.shape],
        "valid_pixels": int(valid.sum()),
        "masked_pixels": int((~valid).sum()),
        "residues": int(np.count_nonzero(residues(np.where(valid, psi, 0.0), valid))),
        "phase_min": lo,
        "phase_max": hi,
        "fringes": (hi - lo) / TWO_PI,
        "seconds": seconds,
    }
