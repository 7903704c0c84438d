"""A static one-page PNG summary of an inspection (for e-mail and tickets).

Verdict banner with its reasons, two views of the scan points coloured by deviation (the colour
scale of every report, :mod:`shapeverify.report.colours`: ``RdBu_r`` centred at 0, clipped at
``2 x`` the tolerance), the histogram with the tolerance limits and the key statistics; with a
plan, its characteristics under them, each with its feature control frame, grouped by datum
reference frame (:mod:`shapeverify.report.png_frames`).  Drawn with matplotlib's Agg canvas
directly (no pyplot, no global backend state), so it works headless and in threads.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np

from .._random import generator
from ..verdict_table import verdict_style
from .colours import CMAP, color_limit
from .ply import check_scan_length
from .png_frames import draw_panel, panel_height
from ..quantities import area_text, length_text

logger = logging.getLogger(__name__)

__all__ = ["png_summary", "summary_figure", "write_png_summary"]



_AXES = ("x", "y", "z")


def _view_frames(p: np.ndarray):
    """Two orthographic views of the points: ``[(title, labels, R (3, 3)), ...]``; a view's rows
    are the screen x, screen y and depth (towards the viewer) directions.

    View 1 looks along the smallest principal axis of the points (at the part's main surface),
    snapped to the nearest model axis when within 25 degrees of it (then its screen axes are model
    axes and are labelled so); view 2 is an oblique view, view 1 turned 35 degrees and tilted 50.
    """
    c = p - p.mean(axis=0)
    _, _, vt = np.linalg.svd(c[:: max(1, len(c) // 5000)], full_matrices=False)
    n = vt[2] if vt.shape[0] == 3 else np.array([0.0, 0.0, 1.0])
    k = int(np.argmax(np.abs(n)))
    if abs(n[k]) > np.cos(np.radians(25.0)):
        i, j = [(1, 2), (2, 0), (0, 1)][k]         # right-handed screen axes for the view along +k
        top = np.eye(3)[[i, j, k]]
        labels = (f"{_AXES[i]} [mm]", f"{_AXES[j]} [mm]")
        title = f"view along the {_AXES[k]} axis"
    else:
        e1, e2 = vt[0], vt[1]
        top = np.stack([e1, e2, np.cross(e1, e2)])
        labels = ("principal axis 1 [mm]", "principal axis 2 [mm]")
        title = "view along the smallest principal axis"
    a, b = np.radians(50.0), np.radians(35.0)
    tilt = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    turn = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
    return [(title, labels, top), ("oblique view", ("mm", "mm"), tilt @ turn @ top)]


def write_png_summary(result, scan=None, path="summary.png", *, max_points: int = 20_000,
                      dpi: int = 110, rng=0) -> Path:
    """Write :func:`png_summary` (a PNG, whatever the suffix) to ``path`` (str or Path);
    parameters and errors as there.

    Returns
    -------
    pathlib.Path
    """
    data = png_summary(result, scan, max_points=max_points, dpi=dpi, rng=rng)
    path = Path(path)
    path.write_bytes(data)
    logger.info("PNG summary written to %s", path)
    return path


def png_summary(result, scan=None, *, max_points: int = 20_000, dpi: int = 110,
                rng=0) -> bytes:
    """The PNG summary of an inspection (views coloured by deviation, histogram, statistics).

    Parameters
    ----------
    result : InspectionResult
    scan : (N, 3) array_like, optional
        The scan as passed to ``inspect``; only its length is checked.
    max_points : int
        Points drawn per view (random subsample, all out-of-tolerance points kept).
    dpi : int
    rng : seed of the subsample.

    Returns
    -------
    bytes
        The PNG file's content.

    Raises
    ------
    ValueError
        If ``scan`` does not have as many points as the inspection.
    """
    fig = summary_figure(result, scan, max_points=max_points, dpi=dpi, rng=rng)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def summary_figure(result, scan=None, *, max_points: int = 20_000, dpi: int = 110, rng=0):
    """The matplotlib :class:`~matplotlib.figure.Figure` of :func:`png_summary` (parameters as
    there), laid out so that no text leaves its place: every text of the banner and of the
    right-hand column is measured once drawn and made smaller (down to 7 pt), then cut with
    "…", until it fits."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    check_scan_length(result, scan)
    dev = result.deviations
    rng = generator(rng)
    tol = result.tolerance
    c_lim = color_limit(tol)
    ev = np.flatnonzero(dev.evaluated)
    if ev.size > max_points:
        within = tol.within(dev.values, dev.face)[ev]
        out, inside = ev[~within], ev[within]
        k = max(0, max_points - out.size)
        ev = np.concatenate([out, rng.choice(inside, size=min(k, inside.size), replace=False)])
    p = dev.points_model[ev]
    v = dev.values[ev]
    ne = np.flatnonzero(~dev.evaluated)
    pn = dev.points_model[ne[:: max(1, ne.size // 5000)]]   # not evaluated: grey, for context
    cov = getattr(result, "coverage", None)
    # the CAD itself, drawn under the scan: seen area light, unseen area darker grey, so that
    # missing data cannot be mistaken for a hole in the part
    cad_pts = cov.points if cov is not None else np.zeros((0, 3))
    cad_seen = cov.covered if cov is not None else np.zeros(0, bool)

    # with a plan: the characteristics panel under the histogram (the page grows by its
    # height; the views, histogram and banner keep their size)
    panel = panel_height(result)
    H = _HEIGHT + panel + (_PANEL_GAP if panel else 0.0)
    fig = Figure(figsize=(12, H), dpi=dpi)
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 3, height_ratios=[0.5, 2.4, 1.5], width_ratios=[1, 1, 0.75],
                          hspace=0.3, wspace=0.18, left=0.06, right=0.98,
                          top=1 - 0.03 * _HEIGHT / H, bottom=(0.07 * _HEIGHT + H - _HEIGHT) / H)
    colour = verdict_style(result.verdict).colour
    ax = fig.add_subplot(gs[0, :])
    ax.set_axis_off()
    ax.add_patch(Rectangle((0, 0), 1, 1, transform=ax.transAxes, color=colour))
    tol_text = (f"±{tol.upper:.4g} mm" if tol.lower == -tol.upper
                else f"[{tol.lower:+.4g}, {tol.upper:+.4g}] mm")
    fits = []                      # (text, its box in axes fractions of `in_axes`, in_axes)
    fits.append((ax.text(0.015, 0.62, verdict_style(result.verdict).word, color="white", fontsize=26,
                         weight="bold", va="center", transform=ax.transAxes),
                 (0.005, 0.0, 0.165, 1.0), ax))
    reason = result.reasons[0] if result.reasons else "all deviations within tolerance"
    inp = getattr(result, "inputs", None) or {}
    ids = "  ·  ".join(f"{k} {inp[k]}" for k in ("part", "scan", "model") if inp.get(k))
    cov_text = "" if cov is None else f"  ·  coverage {100 * cov.fraction:.1f} %"
    fits.append((ax.text(0.17, 0.84, f"tolerance {tol_text}  ·  {dev.n_evaluated:,} of {dev.n:,} "
                         f"points evaluated{cov_text}  ·  {len(result.regions)} region(s)  ·  "
                         f"rule: {getattr(result, 'rule', '') or '–'}",
                         color="white", fontsize=11, va="center", transform=ax.transAxes),
                 (0.17, 0.68, 0.995, 1.0), ax))
    if ids:
        fits.append((ax.text(0.17, 0.55, ids, color="white", fontsize=9, va="center",
                             transform=ax.transAxes), (0.17, 0.40, 0.995, 0.70), ax))
    fits.append((ax.text(0.17, 0.24, reason, color="white", fontsize=10, va="center",
                         transform=ax.transAxes), (0.17, 0.0, 0.995, 0.40), ax))


    norm = Normalize(-c_lim, c_lim)
    p_all = p if len(p) >= 3 else np.vstack([p, pn])
    frames = (_view_frames(p_all) if len(p_all) >= 3 else
              [("view along z", ("x [mm]", "y [mm]"), np.eye(3))] * 2)
    sc = None
    to_label = []                  # (axes, origin, R): region labels, placed once laid out
    for col, (name, labels, R) in enumerate(frames):
        a2 = fig.add_subplot(gs[1, col])
        # view 1 in model coordinates, view 2 about the centre of the points
        origin = np.zeros(3) if col == 0 or len(p_all) == 0 else p_all.mean(axis=0)
        if len(cad_pts):
            qc = (cad_pts - origin) @ R.T
            a2.scatter(qc[cad_seen, 0], qc[cad_seen, 1], c="#e6e6e6", s=1.0, linewidths=0,
                       rasterized=True)
            a2.scatter(qc[~cad_seen, 0], qc[~cad_seen, 1], c="#9e9e9e", s=1.0, linewidths=0,
                       rasterized=True, label="CAD not seen")
        if len(pn):
            qn = (pn - origin) @ R.T
            a2.scatter(qn[:, 0], qn[:, 1], c="#c8c8c8", s=1.0, linewidths=0, rasterized=True,
                       label="not evaluated")
        if len(p):
            q = (p - origin) @ R.T
            order = np.argsort(q[:, 2])                   # painter's order: far points first
            sc = a2.scatter(q[order, 0], q[order, 1], c=v[order], cmap=CMAP, norm=norm, s=1.5,
                            linewidths=0, rasterized=True)
            to_label.append((a2, origin, R))
        a2.set_aspect("equal", adjustable="datalim")
        a2.set_title(name, fontsize=10)
        a2.set_xlabel(labels[0], fontsize=8)
        a2.set_ylabel(labels[1], fontsize=8)
        a2.tick_params(labelsize=7)
    host = fig.add_subplot(gs[1, 2])
    host.set_axis_off()
    if sc is not None:
        cax = host.inset_axes([0.0, 0.05, 0.06, 0.9])
        cb = fig.colorbar(sc, cax=cax)
        cb.set_label("deviation [mm]")
        cb.set_ticks(sorted({-c_lim, tol.lower, 0.0, tol.upper, c_lim}))
        for y in (tol.lower, tol.upper):
            cb.ax.axhline(y, color="black", linewidth=1.5)

    s = result.statistics
    ah = fig.add_subplot(gs[2, :2])
    vals = dev.values[dev.evaluated]
    if vals.size:
        # the axis covers every evaluated inlier (min and max of the statistics) and the limits
        extreme = max(abs(s.min), abs(s.max)) if s.n else float(np.abs(vals).max())
        span = max(1.5 * c_lim, 1.05 * float(extreme))
        _, edges, patches = ah.hist(vals, bins=120, range=(-span, span), color="#4c72b0")
        centres = 0.5 * (edges[:-1] + edges[1:])
        for c, patch in zip(centres, patches):
            if c < tol.lower or c > tol.upper:
                patch.set_facecolor("#d6604d")
        ah.set_xlim(-span, span)
    for x in (tol.lower, tol.upper):
        ah.axvline(x, color="#b3261e", linestyle="--", linewidth=1.5)
    ah.axvline(0.0, color="#333333", linestyle=":", linewidth=1)
    ah.set_xlabel("signed deviation [mm] (+ material added, − missing; dashed: tolerance limits)")
    ah.set_ylabel("points")

    lines = [("mean", s.mean), ("std", s.std), ("RMS", s.rms), ("min", s.min), ("max", s.max),
             ("p05", s.p05), ("p95", s.p95)]
    # decimals that give the tolerance three significant digits (4 for 0.2 mm, 6 for 0.002 mm)
    nd = _decimals(tol)
    text = "deviation statistics [mm]\n"
    if s.n:
        text += "\n".join(f"{k:>4s} {val:+{nd + 5}.{nd}f}" for k, val in lines)
        text += (f"\nin tolerance {100 * s.in_tolerance_fraction:.2f} %\nof "
                 f"{int(result.deviations.n_evaluated):,} evaluated points"
                 f"\n(outliers: {result.outliers.n:,})")
    else:
        text += "no points evaluated"
    n_ne = dev.n - dev.n_evaluated
    if n_ne:
        text += f"\nnot evaluated {n_ne:,} (grey)"
    x_stats = 0.36
    if sc is not None:                # right of the colour bar with its tick labels and label
        fig.canvas.draw()
        right = cax.get_tightbbox(fig.canvas.get_renderer()).x1 + 0.01 * host.bbox.width
        x_stats = max(x_stats, (right - host.bbox.x0) / host.bbox.width)
    fits.append((host.text(x_stats, 0.95, text, family="monospace", fontsize=9, va="top",
                           transform=host.transAxes), (x_stats, None, None, 0.95), fig))

    at = fig.add_subplot(gs[2, 2])
    at.set_axis_off()
    reg, fit = result.registration, result.fit
    fi = fit["inlier_fraction"]
    text = (f"fit: rms {float(fit['rms'] if fit['rms'] is not None else float('nan')):.{nd}f} mm"
            f"\n  inliers {100 * fi:.1f} % (evaluated,\n  less outliers)" if fi is not None else
            "fit: -")
    text += f"\nregistration: {int(reg.iterations)} iterations,\n  converged {bool(reg.converged)}"
    text += f"\n\nregions (most severe first): {len(result.regions)}"
    for i, g in enumerate(result.regions[:4]):
        ext = length_text(g.extreme, signed=True) if np.isfinite(g.extreme) else "seen through"
        text += (f"\n  R{i + 1} {g.kind[:3]}: {ext}, "
                 f"{area_text(g.area)}, {g.n:,} pts")
    text += f"\nmeasurement outliers: {result.outliers.n:,}"
    fits.append((at.text(0.0, 1.0, text, family="monospace", fontsize=9, va="top",
                         transform=at.transAxes), (0.0, None, None, 1.0), fig))
    _fit_texts(fig, fits, floor=(panel + 0.05 + _PANEL_GAP / 2) * fig.dpi if panel else 0.0)
    if panel:
        draw_panel(fig, result, 0.06 * 12, panel + 0.05, (0.98 - 0.06) * 12)
    for a2, origin, R in to_label:
        _label_regions(a2, result.regions, origin, R)
    return fig


_MIN_FONT = 7.0
_HEIGHT = 8.6                # inches: the page without the characteristics panel
_PANEL_GAP = 0.15            # inches between the histogram's label and the panel
_PAD = 0.006                 # of the figure's width: room kept free at its right-hand edge


def _decimals(tol) -> int:
    """Decimals of mm that show the tolerance's smaller limit with three significant digits
    (at least 4)."""
    lim = min((abs(x) for x in (tol.lower, tol.upper) if x), default=1.0)
    return int(max(4, 2 - np.floor(np.log10(lim))))


def _box_pixels(fig, text, box, owner, floor: float = 0.0):
    """``box`` (x0, y0, x1, y1; None: the figure's edge) as display pixels: fractions of the
    axes ``owner``, or of the text's own axes clipped to the figure when ``owner`` is the
    figure (its lower edge then ``floor`` pixels: above the characteristics panel)."""
    W, H = fig.bbox.width, fig.bbox.height
    if owner is fig:
        ab = text.axes.bbox
        x0 = ab.x0 + box[0] * ab.width if box[0] is not None else 0.0
        y1 = ab.y0 + box[3] * ab.height if box[3] is not None else H
        return x0, floor, W * (1 - _PAD), min(y1 + 1.0, H)
    ab = owner.bbox
    return (ab.x0 + box[0] * ab.width, ab.y0 + box[1] * ab.height,
            ab.x0 + box[2] * ab.width, ab.y0 + box[3] * ab.height)


def _fit_texts(fig, fits, floor: float = 0.0) -> None:
    """Shrink (to :data:`_MIN_FONT`) and then cut with "…" each text until its drawn extent
    (``get_window_extent``) lies inside its box (``floor``: pixels from the figure's bottom
    that the texts of the right-hand column leave free)."""
    renderer = fig.canvas.get_renderer()
    for text, box, owner in fits:
        x0, y0, x1, y1 = _box_pixels(fig, text, box, owner, floor)

        def fits_now():
            bb = text.get_window_extent(renderer)
            return (bb.x0 >= x0 - 0.5 and bb.x1 <= x1 + 0.5 and bb.y0 >= y0 - 0.5
                    and bb.y1 <= y1 + 0.5)

        while not fits_now() and text.get_fontsize() > _MIN_FONT:
            text.set_fontsize(max(_MIN_FONT, text.get_fontsize() * 0.9))
        while not fits_now():
            lines = text.get_text().split("\n")
            bb = text.get_window_extent(renderer)
            if bb.y0 < y0 - 0.5 or bb.y1 > y1 + 0.5:
                if len(lines) == 1:
                    break
                lines = lines[:-2] + ["…"]          # the last lines give way to "…"
            else:
                i = max(range(len(lines)), key=lambda k: len(lines[k]))
                if len(lines[i]) <= 2:
                    break
                keep = int(len(lines[i]) * (x1 - max(x0, bb.x0)) / max(bb.width, 1.0)) - 1
                lines[i] = lines[i][:max(1, min(keep, len(lines[i]) - 2))].rstrip() + "…"
            text.set_text("\n".join(lines))


def _label_regions(ax, regions, origin, R, most: int = 9) -> list:
    """Label the most severe regions R1, R2, ... on leader lines where no label meets another
    (:func:`shapeverify.report.labels.place_labels`); a region whose label finds no free place
    is left unlabelled here (it is still in the numbered list beside the views)."""
    from .labels import place_labels

    regions = list(regions[:most])
    if not regions:
        return []
    xy = (np.array([g.centroid for g in regions], float) - origin) @ R.T
    return place_labels(ax, xy[:, :2], [f"R{i + 1}" for i in range(len(regions))])
