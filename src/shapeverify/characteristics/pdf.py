"""PDF report of a plan inspection (matplotlib's PDF backend, ``PdfPages``; no pyplot).

Page 1: header (part id, scan file, model, date, alignment, verdict), colour map of the
deviations in discrete tolerance bands with the CAD area the scan does not cover in grey, the
check points as whiskers (a line along the CAD normal, scaled, with the value), and the
histogram with the tolerance limits.  Page 2: the characteristic table (nominal, measured,
zone, deviation, uncertainty U, verdict), grouped by datum reference frame ("DRF A|B|C", then
the characteristics without datums), each with its feature control frame as the drawing writes
it (:mod:`shapeverify.report.fcf`: symbol, zone, modifiers, datums; a size as its dimension
``Ø20.000 +0.05/−0.05``).  Page 3 (when the plan has a ``section``): the
deviation along the cross-section, with whiskers from the CAD line to each point.

Bands: the band width is the *band tolerance* ``b`` (the half-width t/2 of the plan's first
surface profile, or ``tolerance``): ``(-inf, -2b, -b, -b/2, b/2, b, 2b, inf)``, green inside
±b/2, yellow/cyan to ±b, orange/blue to ±2b, red/purple beyond.
"""
from __future__ import annotations

import datetime as _dt
import logging
from pathlib import Path

import numpy as np

from .._random import generator
from ..report.colours import BAND_COLOURS  # noqa: F401 (re-exported: the PDF's bands)
from ..verdict_table import verdict_style
from .registry import label as _type_label   # the type's label (the registry)
from dataclasses import dataclass
from shapeverify._renamed import grouped_keywords

__all__ = ["ReportLabels", "write_pdf_report", "pdf_figures", "band_edges", "BAND_COLOURS"]

logger = logging.getLogger(__name__)

#: colour of a characteristic's own verdict that is not an inspection verdict (ISO 14253-1)
_UNDECIDED = "#a15c00"


def _colour(verdict) -> str:
    """Colour of an inspection's or a characteristic's verdict (the inspection's from
    :data:`shapeverify.verdict_table.VERDICT_TABLE`)."""
    return _UNDECIDED if verdict == "undecided" else verdict_style(verdict).colour


def band_edges(b: float) -> np.ndarray:
    """Inner band edges (6,) for band tolerance ``b`` (mm): ``b * [-2, -1, -0.5, 0.5, 1, 2]``."""
    return float(b) * np.array([-2.0, -1.0, -0.5, 0.5, 1.0, 2.0])


def _band_tolerance(result, tolerance):
    if tolerance is not None:
        return float(tolerance)
    for c in result.plan.characteristics:
        if c.type == "surface_profile":
            t = c.tol if c.tol is not None else (c.upper - c.lower)
            return 0.5 * float(t)
    return 0.1


def _view(points):
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd((points - c)[:: max(1, len(points) // 5000)], full_matrices=False)
    n = vt[2]
    k = int(np.argmax(np.abs(n)))
    if abs(n[k]) > np.cos(np.radians(25)):
        i, j = [(1, 2), (2, 0), (0, 1)][k]
        return np.eye(3)[[i, j, k]], ("xyz"[i] + " [mm]", "xyz"[j] + " [mm]")
    return np.stack([vt[0], vt[1], np.cross(vt[0], vt[1])]), ("axis 1 [mm]", "axis 2 [mm]")


def _mm(v: float) -> str:
    """A coordinate in mm to the µm, without trailing zeros.

    >>> _mm(28000.0), _mm(-0.0), _mm(12.3456)
    ('28000', '0', '12.346')
    """
    text = f"{float(v):.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _fmt(v, digits=4):
    if v is None:
        return "-"
    if isinstance(v, dict):
        parts = []
        for k, x in v.items():
            if k == "center" and isinstance(x, (list, tuple, np.ndarray)):
                # one coordinate a line: a table cell holds "x=28000.001", not all three
                parts += [f"{a}={_mm(y)}" for a, y in zip("xyz", x)]
            elif x is not None:
                parts.append(f"{'pos' if k == 'position' else k[0]}={x:.{digits}g}")
        return "\n".join(parts)
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(f"{y:.3f}" for y in v) + ")"
    return f"{v:.{digits}g}"


@dataclass(frozen=True)
class ReportLabels:
    """What the PDF's header names (:func:`write_pdf_report`'s ``labels=``; the loose keywords
    of these names still work, with a DeprecationWarning)."""

    part: str | None = None
    scan_file: str | None = None
    model_file: str | None = None
    date: _dt.datetime | str | None = None


@grouped_keywords("labels", ReportLabels)
def write_pdf_report(result, path, prep=None, *, tolerance: float | None = None,
                     max_points: int = 40_000, rng=0, regions=None,
                     labels: ReportLabels = ReportLabels()) -> Path:
    """Write the PDF report of a :class:`~shapeverify.characteristics.evaluate.PlanResult`.

    Parameters
    ----------
    result : PlanResult
    path : str or Path
        Output ``.pdf``.
    prep : Prepared, optional
        The model: its points show the CAD area the scan does not cover (grey).
    labels : ReportLabels
        Groups ``part``, ``scan_file``, ``model_file``, ``date`` (described below); the
        loose keywords still work, with a DeprecationWarning.
    part, scan_file, model_file : str, optional
        Shown in the header (part id default: the plan's ``part``).
    date : datetime or str, optional
        Shown in the header and stored as the PDF's dates (default: now, UTC).
    tolerance : float, optional
        Band tolerance b (mm); default half the first surface profile's t, else 0.1.
    max_points : int
        Points drawn in the colour map (a seeded random subset beyond).
    regions : sequence of DefectRegion, optional
        The inspection's regions (most severe first, model coordinates): labelled R1, R2, ...
        on the map where their labels do not overlap, and listed under it.

    Returns
    -------
    Path

    Raises
    ------
    OSError
        The file cannot be written.
    """
    part = labels.part
    scan_file = labels.scan_file
    model_file = labels.model_file
    date = labels.date
    from matplotlib.backends.backend_pdf import PdfPages

    path = Path(path)
    if date is None:
        date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0)
    part = part if part is not None else (result.plan.part or "-")
    meta = {"Title": f"Inspection report {part}", "Creator": "shapeverify",
            "Subject": f"scan {scan_file or '-'}"}
    if isinstance(date, _dt.datetime):
        meta["CreationDate"] = date
        meta["ModDate"] = date
    figures = pdf_figures(result, prep, part=part, scan_file=scan_file, model_file=model_file,
                          date=date, tolerance=tolerance, max_points=max_points, rng=rng,
                          regions=regions)
    with PdfPages(path, metadata=meta) as pdf:
        for fig in figures:
            pdf.savefig(fig)
    logger.info("PDF report written to %s", path)
    return path


def pdf_figures(result, prep=None, *, part: str | None = None, scan_file: str | None = None,
                model_file: str | None = None, date=None, tolerance: float | None = None,
                max_points: int = 40_000, rng=0, regions=None) -> list:
    """The pages of :func:`write_pdf_report` as matplotlib figures (A4 portrait, the
    cross-section A4 landscape), for writing and for checking their layout (parameters as
    there)."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    rng = generator(rng)
    if date is None:
        date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0)
    stamp = date.isoformat() if isinstance(date, _dt.datetime) else str(date)
    part = part if part is not None else (result.plan.part or "-")
    b = _band_tolerance(result, tolerance)
    edges = band_edges(b)
    cmap = ListedColormap(BAND_COLOURS)
    norm = BoundaryNorm(np.r_[-1e9, edges, 1e9], cmap.N)
    figures = [_page_map(result, prep, part, scan_file, model_file, stamp, b, edges, cmap,
                         norm, max_points, rng, list(regions or ()))]
    figures += _pages_table(result, part)
    if result.section is not None:
        figures.append(_page_section(result.section, b, cmap, norm))
    return figures


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)              # text extents measured as drawn (labels, table rows)
    return fig


def _page_map(result, prep, part, scan_file, model_file, stamp, b, edges, cmap, norm,
              max_points, rng, regions):
    """Page 1: header, the colour map of the deviations (regions labelled), the histogram."""
    X = result.points
    dev = result.deviations
    ok = np.isfinite(dev)
    idx = np.flatnonzero(ok)
    if idx.size > max_points:
        idx = np.sort(rng.choice(idx, max_points, replace=False))
    R, labels = _view(X[ok] if ok.any() else X)
    fig = _figure(*A4_PORTRAIT)
    v = result.verdict
    fig.text(0.06, 0.965, "Inspection report", fontsize=17, weight="bold", va="top")
    fig.text(0.94, 0.965, verdict_style(v).word, fontsize=17, weight="bold", va="top", ha="right",
             color=_colour(v))
    al = result.alignment
    head = [("part", part), ("scan file", scan_file or "-"), ("model", model_file or "-"),
            ("date", stamp), ("alignment", f"{al.kind} (rms {al.rms:.4f} mm; fitted "
                                           f"{' '.join(al.dof_fitted)}"
                                           + (f"; locked {' '.join(al.dof_locked)}"
                                              if al.dof_locked else "") + ")"),
            ("units", "mm; deviations along the CAD normal, + outside the material")]
    for i, (k, val) in enumerate(head):
        fig.text(0.06, 0.93 - 0.018 * i, f"{k}:", fontsize=9, weight="bold", va="top")
        _fit_width(fig, fig.text(0.2, 0.93 - 0.018 * i, str(val), fontsize=9, va="top"))
    ax = fig.add_axes([0.08, 0.40, 0.78, 0.40])
    if prep is not None:
        mp = prep.points.points
        mp = mp[:: max(1, len(mp) // 60000)]
        P2 = mp @ R.T
        ax.scatter(P2[:, 0], P2[:, 1], s=0.6, c="#c8c8c8", linewidths=0, rasterized=True,
                   label="CAD not covered")
    S2 = X[idx] @ R.T
    order = np.argsort(S2[:, 2])
    sc = ax.scatter(S2[order, 0], S2[order, 1], s=1.2, c=dev[idx][order], cmap=cmap,
                    norm=norm, linewidths=0, rasterized=True)
    span = np.ptp(S2[:, :2], axis=0).max() if len(S2) else 1.0
    for c in result.characteristics:
        if c.type == "check_point" and c.measured is not None:
            q = np.asarray(c.details["point"])
            n = np.asarray(c.details["normal"])
            q2, n2 = q @ R.T, n @ R.T
            L = 0.08 * span * float(np.clip(c.measured / max(b, 1e-12), -3, 3))
            end = q2[:2] + L * (n2[:2] / max(np.linalg.norm(n2[:2]), 1e-9)) \
                if np.linalg.norm(n2[:2]) > 1e-3 else q2[:2] + [0, L]
            col = _colour(c.verdict)
            ax.plot([q2[0], end[0]], [q2[1], end[1]], color=col, lw=2)
            ax.plot(*q2[:2], "o", color=col, ms=3)
            ax.annotate(f"{c.name} {c.measured:+.3f}", end, fontsize=7, color=col)
        if c.type == "hole" and c.measured is not None:
            q2 = np.asarray(c.measured["center"]) @ R.T
            ax.annotate(c.name, q2[:2], fontsize=7, ha="center", va="center", weight="bold")
    ax.set_aspect("equal")
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_title(f"Deviation map, bands of b = {b:g} mm (grey: CAD not covered by the scan)",
                 fontsize=10)
    cax = fig.add_axes([0.88, 0.40, 0.02, 0.40])
    cb = fig.colorbar(sc, cax=cax, ticks=edges, spacing="uniform")
    cb.ax.set_yticklabels([f"{e:+.3g}" for e in edges], fontsize=7)
    cb.set_label("deviation [mm]", fontsize=8)
    if regions:
        _region_list(fig, regions)
    hx = fig.add_axes([0.1, 0.06, 0.8, 0.2])
    dv = dev[ok]
    if dv.size:
        lim = histogram_limit(dv, b)
        bins = np.linspace(-lim, lim, 81)
        cnt, be = np.histogram(np.clip(dv, -lim, lim), bins)
        mids = 0.5 * (be[1:] + be[:-1])
        hx.bar(mids, cnt, width=np.diff(be), color=cmap(norm(mids)), edgecolor="none")
        for e in (-b, b):
            hx.axvline(e, color="#b3261e", ls="--", lw=1)
        hx.set_title(f"Histogram of {dv.size:,} deviations: mean {dv.mean():+.4f}, std "
                     f"{dv.std():.4f}, min {dv.min():+.4f}, max {dv.max():+.4f} mm",
                     fontsize=9)
    hx.set_xlabel("deviation [mm]")
    hx.set_ylabel("points")
    _keep_inside(fig, [ax, hx])
    if regions:                      # last: the map's limits and aspect are final
        from shapeverify.report.labels import place_labels

        xy = np.array([np.asarray(g.centroid, float) for g in regions[:9]]) @ R.T
        place_labels(ax, xy[:, :2], [f"R{i + 1}" for i in range(len(xy))], fontsize=8)
    return fig


def _keep_inside(fig, axes, margin: float = 0.02) -> None:
    """Move and narrow each of ``axes`` until it and its tick labels and axis labels lie
    inside the page with ``margin`` (of the page) to spare: a 40 m part's long tick labels
    pushed the map's y label off the page."""
    for ax in axes:
        for _ in range(6):
            fig.canvas.draw()
            tb = ax.get_tightbbox(fig.canvas.get_renderer())
            W, H = fig.bbox.width, fig.bbox.height
            left = max(0.0, margin * W - tb.x0) / W
            right = max(0.0, tb.x1 - (1 - margin) * W) / W
            if left <= 1e-4 and right <= 1e-4:
                break
            pos = ax.get_position()
            ax.set_position([pos.x0 + 1.1 * left, pos.y0, pos.width - 1.1 * (left + right),
                             pos.height])


def _region_list(fig, regions, most: int = 6) -> None:
    """The numbered list of regions under the map (their labels on it are R1, R2, ...)."""
    from shapeverify.quantities import area_text, length_text

    lines = []
    for i, g in enumerate(regions[:most]):
        ext = length_text(g.extreme, signed=True) if np.isfinite(g.extreme) else "seen through"
        c = ", ".join(f"{x:.1f}" for x in g.centroid)
        lines.append(f"R{i + 1}  {g.kind}: {ext}, {area_text(g.area)}, {g.n:,} points, "
                     f"at ({c}) mm")
    if len(regions) > most:
        lines.append(f"... and {len(regions) - most} more (in the HTML report and the JSON)")
    fig.text(0.08, 0.355, f"Regions (most severe first): {len(regions)}", fontsize=9,
             weight="bold", va="top")
    _fit_width(fig, fig.text(0.08, 0.338, "\n".join(lines), fontsize=8, va="top",
                             family="monospace", linespacing=1.3))


def _fit_width(fig, text, right: float = 0.96) -> None:
    """Cut each line of ``text`` with "…" until it ends left of ``right`` (of the page width),
    measured as drawn (a 259-character part id ran off the page)."""
    renderer = fig.canvas.get_renderer()
    limit = right * fig.bbox.width
    lines = text.get_text().split("\n")
    for _ in range(200):
        bb = text.get_window_extent(renderer)
        if bb.x1 <= limit:
            return
        i = max(range(len(lines)), key=lambda k: len(lines[k]))
        if len(lines[i]) <= 2:
            return
        keep = int(len(lines[i]) * (limit - bb.x0) / max(bb.width, 1.0)) - 1
        lines[i] = _clip(lines[i], max(2, min(keep, len(lines[i]) - 1)))
        text.set_text("\n".join(lines))


def _fit_cells(fig, tab) -> None:
    """Cut a cell's too-long lines with "…" (a 259-character name) until its text lies
    inside the cell, measured as drawn; the font stays 8.5 pt."""
    for cell in tab.get_celld().values():
        cell.PAD = 0.05
    fig.canvas.draw()                    # places each cell and its text once
    renderer = fig.canvas.get_renderer()
    for cell in tab.get_celld().values():
        text = cell.get_text()
        for _ in range(200):
            box, bb = cell.get_window_extent(renderer), text.get_window_extent(renderer)
            if bb.x0 >= box.x0 and bb.x1 <= box.x1:
                break
            lines = text.get_text().split("\n")
            i = max(range(len(lines)), key=lambda k: len(lines[k]))
            if len(lines[i]) <= 2:
                break
            keep = int(len(lines[i]) * box.width / max(bb.width, 1.0))
            lines[i] = _clip(lines[i], max(2, min(keep, len(lines[i]) - 1)))
            text.set_text("\n".join(lines))


def _clip(text: str, n: int) -> str:
    """``text`` cut to ``n`` characters with "…" (a long part id must not run off the page).

    >>> _clip("SN-0042", 10), _clip("x" * 12, 10)
    ('SN-0042', 'xxxxxxxxx…')
    """
    return text if len(text) <= n else text[: n - 1] + "…"


#: characteristics per table page at most (A4 portrait, 8.5 pt)
ROWS_PER_PAGE = 30
_ROW_BASE, _ROW_LINE = 0.008, 0.0125     # a row's height: fractions of the table's axes
_TABLE_ROOM = 0.95                       # of the table's axes, under the header row
_COLS = ["characteristic", "feature control frame", "nominal", "measured", "zone",
         "deviation", "U", "verdict"]
_WIDTHS = [0.15, 0.22, 0.10, 0.14, 0.10, 0.11, 0.08, 0.10]
_FCF_COL = 1
_FRAME_H, _FRAME_FONT, _FRAME_MIN_FONT = 10.5, 8.0, 5.5   # points


def _zone(c) -> str:
    """The zone (limits) of a result: ``≤ t`` for a zone width (upper limit only), the upper
    over the lower limit for a two-sided one; a hole's per key."""
    from .registry import one_sided_types

    def one(key, lo, hi):
        if hi is None:
            return "-"
        if key in one_sided_types() or lo is None:
            return f"≤ {_fmt(hi)}"
        return f"{float(hi):+.4g}\n{float(lo):+.4g}"           # upper over lower

    if isinstance(c.upper, dict):
        lo = c.lower if isinstance(c.lower, dict) else {}
        return "\n".join(f"{'pos' if k == 'position' else k[0]}: {one(k, lo.get(k), v)}"
                          for k, v in c.upper.items())
    return one(c.type, c.lower, c.upper)


def _table_entries(result):
    """``[("head", datums) | ("row", (cells, frames, colour)), ...]``: the characteristics
    grouped by datum reference frame (:func:`shapeverify.report.fcf.group_by_drf`), each
    group under its heading."""
    from ..report.fcf import composite_frames, composite_pairs, frames, group_by_drf
    from .zone_noise import noise_note

    plan = {c.name: c for c in result.plan.characteristics}
    fs_of = {c.name: frames(c, plan.get(c.name)) for c in result.characteristics}
    # a composite frame's two segments: adjacent rows, one frame drawn across both (the 4th
    # element: ("upper", lower name, (upper frame, lower frame)) | ("lower", upper name))
    pairs = composite_pairs(plan.values())
    role: dict = {}
    for lo, up in pairs.items():
        both = composite_frames(fs_of[up], fs_of[lo]) if up in fs_of and lo in fs_of else None
        if both is not None:
            role[up], role[lo] = ("upper", lo, both), ("lower", up)
    items = []
    for c in result.characteristics:
        note = noise_note(c.details, sep="\n")
        measured = _fmt(c.measured) + (f"\n{note}" if note else "")
        cells = [c.name, "", _fmt(c.nominal), measured, _zone(c), _fmt(c.deviation),
                 _fmt(c.uncertainty, 3), c.verdict]
        items.append((cells, fs_of[c.name], _colour(c.verdict), role.get(c.name)))
    out = []
    follows = {lo: r[1] for lo, r in role.items() if r[0] == "lower"}
    for drf, group in group_by_drf(items, follows=follows, name=lambda it: it[0][0]):
        out.append(("head", drf))
        out += [("row", it) for it in group]
    return out


def _entry_height(entry) -> float:
    if entry[0] == "head":
        return _ROW_BASE + _ROW_LINE
    cells, fs = entry[1][:2]
    lines = max(max(str(x).count("\n") + 1 for x in cells), len(fs))
    return _ROW_BASE + _ROW_LINE * lines


def _paginate(entries) -> list[list]:
    """The entries page by page: as many as fit under the header row (at most
    :data:`ROWS_PER_PAGE` characteristics); a page that starts inside a group repeats its
    heading (``("head", datums, True)``: continued)."""
    pages, page, used, rows, drf = [], [], 0.0, 0, None
    for e in entries:
        h = _entry_height(e)
        full = used + h > _TABLE_ROOM or (e[0] == "row" and rows >= ROWS_PER_PAGE)
        if e[0] == "head" and used + h + _entry_height(("row", ([""], (), None))) > _TABLE_ROOM:
            full = True                        # no heading alone at a page's foot
        if page and full:
            pages.append(page)
            page, used, rows = [], 0.0, 0
            if e[0] == "row":
                page.append(("head", drf, True))
                used += _entry_height(page[-1])
        if e[0] == "head":
            drf = e[1]
        else:
            rows += 1
        page.append(e)
        used += h
    return pages + [page] if page else [[]]


def _pages_table(result, part):
    """Page 2 (and more for a long plan): the characteristics table, A4 portrait, grouped by
    datum reference frame, each row with its feature control frame(s)."""
    from ..report.fcf import drf_title

    chunks = _paginate(_table_entries(result)) if result.characteristics else [[]]
    pages = []
    for k, chunk in enumerate(chunks):
        fig = _figure(*A4_PORTRAIT)
        more = f" ({k + 1}/{len(chunks)})" if len(chunks) > 1 else ""
        _fit_width(fig, fig.text(0.05, 0.965, f"Characteristics — part {part}{more}",
                                 fontsize=14, weight="bold", va="top"))
        fig.text(0.05, 0.935, "U: expanded uncertainty (k = "
                 f"{result.plan.coverage_factor:g}); verdict by ISO 14253-1 (undecided: "
                 "within U of a limit). mm.\nZone widths (profile, flatness, position ...) "
                 "have an upper limit only (≤); with a material modifier (M, L)\nthe zone "
                 "includes the bonus tolerance of the measured size. Grouped by datum "
                 "reference frame (DRF).", fontsize=8.5, va="top")
        tx = fig.add_axes([0.04, 0.04, 0.92, 0.86])
        tx.axis("off")
        if chunk:
            body = [[""] * len(_COLS) if e[0] == "head" else list(e[1][0]) for e in chunk]
            tab = tx.table(cellText=body, colLabels=_COLS, loc="upper center",
                           cellLoc="center", colWidths=_WIDTHS)
            tab.auto_set_font_size(False)
            tab.set_fontsize(8.5)
            for r, e in enumerate(chunk, start=1):
                for j in range(len(_COLS)):
                    tab[r, j].set_height(_entry_height(e))
                if e[0] == "head":          # one band: no inner edges (its shade: _draw_frames)
                    for j in range(len(_COLS)):
                        tab[r, j].set_facecolor("none")
                        tab[r, j].visible_edges = ("BTL" if j == 0 else
                                                   "BTR" if j == len(_COLS) - 1 else "BT")
                else:
                    tab[r, len(_COLS) - 1].get_text().set_color(e[1][2])
                    tab[r, len(_COLS) - 1].get_text().set_weight("bold")
            for j in range(len(_COLS)):
                tab[0, j].set_facecolor("#e8e8e8")
                tab[0, j].set_height(0.025)
            _fit_cells(fig, tab)
            _draw_frames(fig, tab, chunk, drf_title)
        else:
            no_plan = result.alignment.details.get("source") == "registration"
            tx.text(0.5, 0.5, "no inspection plan: the verdict is the tolerance on every\n"
                    "evaluated point (free best fit of all faces)" if no_plan else
                    "the plan has no characteristics", ha="center", fontsize=10)
        pages.append(fig)
    return pages


def _draw_frames(fig, tab, chunk, drf_title) -> None:
    """The group headings and each row's frames, drawn into the laid-out table (cells placed
    by :func:`_fit_cells`' draw): a frame wider than its cell is drawn smaller, down to
    :data:`_FRAME_MIN_FONT` points."""
    from matplotlib.patches import Rectangle

    from ..report.fcf import composite_width, draw_composite, draw_frame, frame_width

    renderer = fig.canvas.get_renderer()
    to_pt = 72.0 / fig.dpi
    drawn = set()                   # lower segments drawn with their upper
    for r, e in enumerate(chunk, start=1):
        box = tab[r, 0].get_window_extent(renderer)
        if e[0] == "head":
            right = tab[r, len(_COLS) - 1].get_window_extent(renderer)
            title = drf_title(e[1]) + (" (continued)" if len(e) > 2 else "")
            t = fig.text((box.x0 + 4 / to_pt) / fig.bbox.width,
                         (box.y0 + box.height / 2) / fig.bbox.height, title, fontsize=8.5,
                         weight="bold", va="center_baseline", gid="drf-heading")
            _fit_width(fig, t, right.x1 / fig.bbox.width)
            d = fig.dpi                   # inches: in place at any output resolution
            fig.add_artist(Rectangle((box.x0 / d, box.y0 / d), (right.x1 - box.x0) / d,
                                     box.height / d, transform=fig.dpi_scale_trans,
                                     facecolor="#ececec", edgecolor="none", zorder=-1))
            continue
        role = e[1][3] if len(e[1]) > 3 else None
        if role is not None and role[0] == "lower" and e[1][0][0] in drawn:
            continue
        nxt = chunk[r] if r < len(chunk) else None
        if (role is not None and role[0] == "upper" and nxt is not None and nxt[0] == "row"
                and nxt[1][0][0] == role[1]):
            # one frame across the two rows: the symbol cell spans both, the upper segment's
            # row above the rows' boundary, the lower's below; the cells' edge between them
            # in the frame column is not drawn
            up_cell = tab[r, _FCF_COL].get_window_extent(renderer)
            lo_cell = tab[r + 1, _FCF_COL].get_window_extent(renderer)
            tab[r, _FCF_COL].visible_edges = "LRT"
            tab[r + 1, _FCF_COL].visible_edges = "LRB"
            room = up_cell.width * to_pt - 6.0
            size, h = _FRAME_FONT, _FRAME_H
            while size > _FRAME_MIN_FONT and composite_width(fig, *role[2], height=h,
                                                              fontsize=size) > room:
                size, h = size - 0.5, h * (size - 0.5) / size
            y = lo_cell.y1 * to_pt - h
            draw_composite(fig, *role[2], up_cell.x0 * to_pt + 3.0, y, height=h,
                           fontsize=size, gids=(f"fcf:{e[1][0][0]}:0", f"fcf:{role[1]}:0"))
            drawn.add(role[1])
            continue
        cell = tab[r, _FCF_COL].get_window_extent(renderer)
        fs = e[1][1]
        n = len(fs)
        room = cell.width * to_pt - 6.0
        for i, f in enumerate(fs):
            size, h = _FRAME_FONT, _FRAME_H
            while size > _FRAME_MIN_FONT and frame_width(fig, f, height=h,
                                                          fontsize=size) > room:
                size, h = size - 0.5, h * (size - 0.5) / size
            slot = cell.height * to_pt / n
            y = cell.y0 * to_pt + cell.height * to_pt - slot * (i + 1) + (slot - h) / 2
            draw_frame(fig, f, cell.x0 * to_pt + 3.0, y, height=h, fontsize=size,
                       gid=f"fcf:{e[1][0][0]}:{i}")


def _page_section(sec, b, cmap, norm):
    """Page 3: the deviation along the plan's cross-section (A4 landscape)."""
    fig = _figure(A4_PORTRAIT[1], A4_PORTRAIT[0])
    ax = fig.add_axes([0.08, 0.12, 0.86, 0.74])
    s = np.asarray(sec["s"], float)
    d = np.asarray(sec["deviation"], float)
    fig.text(0.04, 0.94, section_title(sec), fontsize=12, weight="bold")
    if s.size:
        k = max(1, s.size // 400)
        for si, di in zip(s[::k], d[::k]):
            ax.plot([si, si], [0, di], color=cmap(norm(di)), lw=0.8)
        ax.scatter(s, d, s=3, c=d, cmap=cmap, norm=norm, linewidths=0, zorder=3)
        ax.axhline(0, color="black", lw=1)
        for e in (-b, b):
            ax.axhline(e, color="#b3261e", ls="--", lw=1)
        ax.set_title(f"{s.size} points within the section band; whiskers: deviation "
                     "from the CAD (every point up to 400)", fontsize=9)
    else:
        ax.text(0.5, 0.5, "no scan points in the section band", ha="center",
                transform=ax.transAxes)
    ax.set_xlabel("position along the section [mm]")
    ax.set_ylabel("deviation [mm]")
    ax.grid(alpha=0.3)
    return fig


#: A4 portrait, inches
A4_PORTRAIT = (8.27, 11.69)


def histogram_limit(dv, b: float) -> float:
    """Half-width of the histogram's axis: three band widths, or more so that the axis covers
    every deviation (the title's min and max; it stopped at -0.3 while the minimum was -0.40).

    >>> round(histogram_limit(np.array([-0.40, 0.0, 0.05]), 0.1), 6)
    0.42
    >>> round(histogram_limit(np.array([-0.02, 0.02]), 0.1), 6)
    0.3
    """
    return max(3 * b, 1.05 * float(np.abs(dv).max()))


def section_title(sec: dict) -> str:
    """Page 3's title: "Cross-section NAME: plane through P with normal N" (without the name
    when the plan gave none: it read "Cross-section section: ...").

    >>> section_title({"name": "section", "plane": ([150.0, 100.0, 0.0], [1.0, 0.0, 0.0])})
    'Cross-section: plane through (150.000, 100.000, 0.000) with normal (1.000, 0.000, 0.000)'
    >>> section_title({"name": "A-A", "plane": ([0, 0, 0], [0, 1, 0])})[:17]
    'Cross-section A-A'
    """
    name = str(sec.get("name") or "")
    head = "Cross-section" if name.lower() in ("", "section") else f"Cross-section {name}"
    return f"{head}: plane through {_fmt(sec['plane'][0])} with normal {_fmt(sec['plane'][1])}"
