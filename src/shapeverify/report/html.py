"""The HTML inspection report: one self-contained file that opens offline in any browser.

Contents: a verdict banner with its reasons; an interactive 3D view (plotly) of the scan points in
model coordinates, coloured by deviation on a diverging scale centred at 0 and clipped at
``2 x`` the tolerance (the tolerance limits are marked on the colour bar), over the shaded CAD
surface; the histogram of deviations with the tolerance limits; tables of statistics, defect
regions, registration and per-face statistics.  plotly.js is embedded in the file (no CDN), so the
report works without a network (gzip-compressed, unpacked by the browser).  Lengths are in mm
throughout.

Scans with more than ``max_points`` evaluated points are subsampled for the 3D view (all
out-of-tolerance points are kept; the page says so); the histogram and tables use every point.
"""

from __future__ import annotations

import datetime as _dt
import html
import logging
import math
from pathlib import Path

import numpy as np

from .._random import generator
from ..verdict_table import verdict_style
from .colours import CMAP, color_limit
from .fcf import (FCF_CSS, composite_frames, composite_html, composite_pairs, drf_title,
                  frame_html, frames, group_by_drf)
from .labels import free_labels
from ..quantities import area_text, length_text
from .ply import check_scan_length

logger = logging.getLogger(__name__)

__all__ = ["html_report", "write_html_report", "render_html", "cad_mesh", "scene_camera",
           "view_projection"]

_MAX_TRIANGLES = 120_000
_MAX_NOT_EVALUATED = 10_000
#: points drawn in the 3D view by default: keeps the report of a 40,000-point scan under 3 MB
#: (it was 6-7 MB); every out-of-tolerance point is always drawn, and nothing measured is dropped
MAX_POINTS = 20_000


def _fmt(x, digits: int = 4, signed: bool = False) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}"
    return f"{float(x):+.{digits}f}" if signed else f"{float(x):.{digits}f}"


def _length(x) -> str:
    """A signed length with three significant digits in µm, mm or m ("–" when not finite)."""
    return "–" if x is None or not math.isfinite(float(x)) else length_text(x, signed=True)


def _table(rows, header=None, cls="kv") -> str:
    out = [f'<table class="{cls}">']
    if header:
        out.append("<tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in header) + "</tr>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>")
    out.append("</table>")
    return "".join(out)


def _zone(ctype: str, lo, hi, fmt) -> str:
    """A zone: ``≤ t`` for a zone width (the registry's one-sided types: upper limit only),
    ``lower … upper`` for a two-sided one."""
    from ..characteristics.registry import one_sided_types

    if hi is None:
        return "–"
    if ctype in one_sided_types() or lo is None:
        return f"≤&nbsp;{fmt(hi)}"
    return f"{fmt(lo, True)}&nbsp;…&nbsp;{fmt(hi, True)}"


def _characteristics_table(chars, plan_result, fmt) -> str:
    """The characteristics (their JSON dicts) grouped by datum reference frame ("DRF A|B|C",
    then those without datums), each row with its feature control frame(s)
    (:mod:`shapeverify.report.fcf`): frame, nominal, measured, zone, deviation, U, verdict."""
    from shapeverify.characteristics.zone_noise import noise_note

    plan = getattr(plan_result, "plan", None)
    entries = {c.name: c for c in getattr(plan, "characteristics", ())}
    items = [(c, frames(c, entries.get(c["name"]))) for c in chars]
    # a composite frame's two segments: adjacent rows, one frame drawn across both
    pairs = composite_pairs(entries.values())
    fs_of = {c["name"]: fs for c, fs in items}
    joined = {lo: composite_frames(fs_of[up], fs_of[lo]) for lo, up in pairs.items()
              if lo in fs_of and up in fs_of}
    joined = {lo: v for lo, v in joined.items() if v is not None}
    upper_of = {pairs[lo]: lo for lo in joined}
    header = ("characteristic", "feature control frame", "nominal", "measured", "zone",
              "deviation", "uncertainty U (k=2)", "verdict")
    out = ['<table class="regions chars">', "<tr>" + "".join(f"<th>{h}</th>" for h in header)
           + "</tr>"]
    for drf, group in group_by_drf(items, follows={lo: pairs[lo] for lo in joined},
                                   name=lambda it: it[0]["name"]):
        out.append(f'<tr class="drf" data-drf="{html.escape("|".join(drf))}"><th colspan='
                   f'"{len(header)}">{html.escape(drf_title(drf))}</th></tr>')
        for c, fs in group:
            lo, hi = c.get("lower"), c.get("upper")
            if isinstance(hi, dict):
                lo = lo if isinstance(lo, dict) else {}
                zone = "<br>".join(f"{html.escape(k)} {_zone(k, lo.get(k), v, fmt)}"
                                   for k, v in hi.items())
            else:
                zone = _zone(str(c["type"]), lo, hi, fmt)
            v = html.escape(str(c["verdict"]))
            frame_cell = "<td>" + "<br>".join(frame_html(f) for f in fs) + "</td>"
            if c["name"] in upper_of:           # the composite frame spans both rows
                lo = upper_of[c["name"]]
                frame_cell = (f'<td rowspan="2" class="fcf-pair" data-lower="'
                              f'{html.escape(str(lo))}">{composite_html(*joined[lo])}</td>')
            elif c["name"] in joined:           # drawn in its upper's row
                frame_cell = ""
            note = noise_note(c.get("details"))
            measured = fmt(c.get("measured")) + (f'<br><span class="note">{html.escape(note)}'
                                                 '</span>' if note else "")
            cells = (html.escape(str(c["name"])), fmt(c.get("nominal")), measured, zone, fmt(c.get("deviation"), True),
                     fmt(c.get("uncertainty")), f'<b class="v-{v}">{v}</b>')
            out.append(f'<tr data-name="{html.escape(str(c["name"]))}">'
                       + f"<td>{cells[0]}</td>" + frame_cell
                       + "".join(f"<td>{x}</td>" for x in cells[1:]) + "</tr>")
    out.append("</table>")
    return "".join(out)


def cad_mesh(model, max_triangles: int = _MAX_TRIANGLES):
    """A coarse triangulation of the model for drawing: ``(vertices (V, 3), triangles (T, 3))``.

    CAD faces are tessellated on a parameter grid per face (triangles inside the trims kept);
    a mesh model is drawn as is (decimated by dropping triangles if huge).  Returns None for a
    point-cloud model or when there is nothing to draw.
    """
    if model is None or getattr(model, "kind", None) == "points":
        return None
    from ..cad.tessellate import tessellate_model

    if getattr(model, "kind", None) == "cad" and len(model.faces) == 0:
        return None
    edge = model.size / 60.0
    for _ in range(6):
        tess = tessellate_model(model, max_edge=edge, max_per_side=60, cover=False)
        if len(tess.triangles) <= max_triangles or model.kind == "mesh":
            break
        edge *= 1.6
    verts, tris = tess.vertices, tess.triangles
    if len(tris) > max_triangles:          # a huge mesh: draw a subset of its triangles
        tris = tris[:: int(math.ceil(len(tris) / max_triangles))]
    return np.asarray(verts, np.float32), np.asarray(tris, np.int32)


def _subsample(result, max_points: int, rng):
    """Indices of evaluated points for the 3D view: all out-of-tolerance ones plus a random rest."""
    dev = result.deviations
    ev = np.flatnonzero(dev.evaluated)
    if ev.size <= max_points:
        return ev, False
    within = result.tolerance.within(dev.values, dev.face)
    out = ev[~within[ev]]
    inside = ev[within[ev]]
    k = max(0, max_points - out.size)
    pick = rng.choice(inside, size=min(k, inside.size), replace=False) if k else inside[:0]
    return np.sort(np.concatenate([out, pick])), True


def _figure_3d(result, model, idx, c_lim):
    import plotly.graph_objects as go

    dev = result.deviations
    tol = result.tolerance
    traces = []
    mesh = cad_mesh(model)
    if mesh is not None:
        v, t = mesh
        traces.append(go.Mesh3d(
            x=v[:, 0], y=v[:, 1], z=v[:, 2], i=t[:, 0], j=t[:, 1], k=t[:, 2],
            color="#b8bcc2", opacity=0.55, flatshading=False, name="CAD surface",
            showlegend=True, hoverinfo="skip",
            lighting=dict(ambient=0.55, diffuse=0.7, specular=0.15, roughness=0.6)))
    p = dev.points_model[idx].astype(np.float32)
    vals = dev.values[idx].astype(np.float32)
    ticks = sorted({-c_lim, tol.lower, 0.0, tol.upper, c_lim})
    labels = {tol.lower: f"{tol.lower:+.3g} lower", tol.upper: f"{tol.upper:+.3g} upper", 0.0: "0"}
    ticktext = [labels.get(x, f"{x:+.3g}") for x in ticks]
    traces.append(go.Scatter3d(
        x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="markers", name="scan (deviation)",
        marker=dict(size=2, color=vals, colorscale=CMAP, cmin=-c_lim, cmax=c_lim, cmid=0.0,
                    colorbar=dict(title=dict(text="deviation [mm]"), tickvals=ticks,
                                  ticktext=ticktext, len=0.8)),
        customdata=vals,
        hovertemplate="deviation %{customdata:+.4f} mm<br>x %{x:.2f} y %{y:.2f} z %{z:.2f} mm"
                      "<extra></extra>"))
    ne = np.flatnonzero(~dev.evaluated)
    if ne.size:
        ne = ne[:: int(math.ceil(ne.size / _MAX_NOT_EVALUATED))]
        q = dev.points_model[ne].astype(np.float32)
        traces.append(go.Scatter3d(
            x=q[:, 0], y=q[:, 1], z=q[:, 2], mode="markers", name="not evaluated",
            marker=dict(size=1.5, color="#8a8a8a"), hoverinfo="skip", visible="legendonly"))
    cov = getattr(result, "coverage", None)
    if cov is not None and (~cov.covered).any():
        u = cov.points[~cov.covered].astype(np.float32)
        traces.append(go.Scatter3d(
            x=u[:, 0], y=u[:, 1], z=u[:, 2], mode="markers", name="CAD area not seen (no scan data)",
            marker=dict(size=2, color="#9e9e9e"), hoverinfo="skip"))
    drawn = [p] + ([mesh[0]] if mesh is not None else [])
    if cov is not None and (~cov.covered).any():
        drawn.append(u)
    c = np.array([r.centroid for r in result.regions], dtype=np.float64).reshape(-1, 3)
    drawn.append(c)
    camera, project = scene_camera(np.vstack([np.asarray(a, np.float64).reshape(-1, 3)
                                              for a in drawn]), _worst(result))
    if result.regions:
        names = [f"R{i + 1} {r.extreme:+.3f}" if np.isfinite(r.extreme) else f"R{i + 1} {r.kind}"
                 for i, r in enumerate(result.regions)]
        # a label is drawn only where it meets no label drawn before (most severe first) in
        # the opening view; every region keeps its marker, its hover text and its table row
        xy = project(c)
        w = [_LABEL_FONT * 0.62 * len(t) for t in names]
        corners = [(x - wi / 2, y + 6) for (x, y), wi in zip(xy, w)]
        shown = set(free_labels(corners, w, 1.3 * _LABEL_FONT, pad=3.0))
        traces.append(go.Scatter3d(
            x=c[:, 0], y=c[:, 1], z=c[:, 2], mode="markers+text", name="regions (R1 most severe)",
            marker=dict(size=5, color="black", symbol="diamond"),
            text=[t if i in shown else "" for i, t in enumerate(names)],
            hovertext=names, textfont=dict(size=_LABEL_FONT),
            textposition="top center", hoverinfo="text"))
    fig = go.Figure(traces)
    axis = lambda name: dict(title=dict(text=f"{name} [mm]"), backgroundcolor="white")  # noqa: E731
    fig.update_layout(
        scene=dict(aspectmode="data", xaxis=axis("x"), yaxis=axis("y"), zaxis=axis("z"),
                   camera=camera),
        margin=dict(l=0, r=0, t=30, b=0), height=_HEIGHT,
        legend=dict(orientation="h", yanchor="bottom", y=1.0, x=0.0))
    return fig


_HEIGHT = 640                 # px, the 3D view's height
_WIDTH = 900                  # px, the width assumed for the opening view (a laptop's page)
_FOVY = math.pi / 4           # plotly's (gl-plot3d's) vertical field of view
_LABEL_FONT = 11


def _worst(result):
    """(centroid, outward normal) of the most severe region, or None."""
    if not result.regions:
        return None
    g = result.regions[0]
    normals = getattr(result.deviations, "normals", None)   # a stored record keeps none
    if normals is None:
        return np.asarray(g.centroid, np.float64), np.zeros(3)  # the camera picks a side
    n = np.asarray(normals, np.float64)[np.asarray(g.indices)]
    n = n[np.all(np.isfinite(n), axis=1)].mean(axis=0) if len(n) else np.zeros(3)
    return np.asarray(g.centroid, np.float64), n


def scene_camera(points, worst=None, *, width: float = _WIDTH, height: float = _HEIGHT):
    """The opening camera of the 3D view: centred on the worst region (or on the part), looking
    at it from its outward side, tilted 25 degrees so that it is seen in relief, never edge-on,
    and far enough back that the whole part is in view.

    Plotly (``aspectmode="data"``) maps the data to its scene box uniformly: a point ``x`` is
    at ``(x - mid) / (1.0625 G)`` in camera units, ``mid`` the middle of the data's bounding
    box, ``G`` the geometric mean of its three sides (plotly.js ``scene.js``: axis ranges padded
    by 1/32 each side, aspect ratio ``side / G``; gl-plot3d: the padded range maps to ``aspect``).

    Parameters
    ----------
    points : (N, 3) array
        Everything the view draws (it sets plotly's bounding box).
    worst : (centroid (3,), normal (3,)) or None
    width, height : float
        The view's size in pixels (the field of view is vertical, 45 degrees).

    Returns
    -------
    camera : dict
        ``layout.scene.camera`` (eye, center, up).
    project : callable
        ``(M, 3)`` data points -> ``(M, 2)`` pixels (x right, y up) in the opening view.
    """
    norm, lo, side = _scene_frame(points)
    if worst is not None:
        centre, n = norm(worst[0]), np.asarray(worst[1], np.float64)
    else:
        centre, n = np.zeros(3), np.zeros(3)
    if not np.linalg.norm(n) > 1e-9:
        n = np.eye(3)[int(np.argmin(side))]
    n = n / np.linalg.norm(n)
    # tilt: towards +z (or -y for a face looking along z), so the view is in relief
    a = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, -1.0, 0.0])
    t = a - (a @ n) * n
    view = n + np.tan(np.radians(25.0)) * t / np.linalg.norm(t)
    view /= np.linalg.norm(view)
    up = np.array([0.0, 0.0, 1.0]) if abs(view[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    # far enough back that every corner of the (padded) box is in view, with a 10 % margin
    box = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    corners = norm(lo - side / 32 + box * (side * (1 + 1 / 16)))
    right, upv = _screen_axes(view, up)
    tan_y = math.tan(_FOVY / 2)
    tan_x = tan_y * width / height
    rel = corners - centre
    need = np.max(np.maximum(np.abs(rel @ right) / tan_x, np.abs(rel @ upv) / tan_y)
                  + rel @ view)
    eye = centre + 1.1 * max(float(need), 1e-6) * view
    xyz = lambda v: dict(x=float(v[0]), y=float(v[1]), z=float(v[2]))  # noqa: E731
    camera = dict(eye=xyz(eye), center=xyz(centre), up=xyz(up))
    return camera, view_projection(points, camera, width=width, height=height)


def _scene_frame(points):
    """``(norm, lo, side)``: data -> plotly's camera units, and the data's bounding box."""
    P = np.asarray(points, np.float64).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    lo, hi = (P.min(axis=0), P.max(axis=0)) if len(P) else (np.zeros(3), np.ones(3))
    side = np.where(hi > lo, hi - lo, 1.0)
    mid = 0.5 * (lo + hi)
    unit = 1.0625 * float(np.prod(side) ** (1.0 / 3.0))
    return (lambda x: (np.asarray(x, np.float64) - mid) / unit), lo, side


def _screen_axes(view, up):
    right = np.cross(-view, up)
    right /= np.linalg.norm(right)
    return right, np.cross(right, -view)


def view_projection(points, camera, *, width: float = _WIDTH, height: float = _HEIGHT):
    """``project((M, 3) data points) -> (M, 2) pixels`` (x right, y up) of the 3D view of
    ``points`` (which set plotly's box) through ``camera`` (``layout.scene.camera``)."""
    norm, _, _ = _scene_frame(points)
    vec = lambda key: np.array([camera[key][k] for k in "xyz"], np.float64)  # noqa: E731
    eye, centre, up = vec("eye"), vec("center"), vec("up")
    view = (eye - centre) / np.linalg.norm(eye - centre)
    right, upv = _screen_axes(view, up)
    tan_y = math.tan(_FOVY / 2)

    def project(q):
        v = norm(np.asarray(q, np.float64).reshape(-1, 3)) - eye
        depth = np.maximum(v @ -view, 1e-12)
        x = (v @ right) / depth / tan_y * height / 2 + width / 2
        y = (v @ upv) / depth / tan_y * height / 2 + height / 2
        return np.column_stack([x, y])

    return project


def _figure_hist(result, c_lim):
    import plotly.graph_objects as go

    dev = result.deviations
    tol = result.tolerance
    v = dev.values[dev.evaluated]
    span = max(1.5 * c_lim, float(np.percentile(np.abs(v), 99.5)) * 1.05) if v.size else c_lim
    shown = v[np.abs(v) <= span]
    size = 2.0 * span / 120
    inside = (shown >= tol.lower) & (shown <= tol.upper)
    # counted here, 120 bars drawn (not every value sent to the browser to be counted there)
    edges = np.linspace(-span, span, 121)
    mids = (0.5 * (edges[:-1] + edges[1:])).astype(np.float32)
    counts = [np.histogram(shown[m], edges)[0].astype(np.int32) for m in (inside, ~inside)]
    fig = go.Figure([
        go.Bar(x=mids, y=counts[0], width=size, marker_color="#4c72b0", name="in tolerance",
               hovertemplate="%{x:.4g} mm: %{y} points<extra></extra>"),
        go.Bar(x=mids, y=counts[1], width=size, marker_color="#d6604d", name="out of tolerance",
               hovertemplate="%{x:.4g} mm: %{y} points<extra></extra>"),
    ])
    lines = [(tol.lower, f"lower {tol.lower:+.3g} mm", "#b3261e"),
             (tol.upper, f"upper {tol.upper:+.3g} mm", "#b3261e"), (0.0, "", "#333333")]
    for x, label, colour in lines:
        fig.add_vline(x=x, line=dict(color=colour, dash="dash" if label else "dot", width=2),
                      annotation_text=label, annotation_position="top")
    note = f" ({v.size - shown.size:,} points beyond ±{span:.3g} mm not drawn)" if shown.size < v.size else ""
    fig.update_layout(
        xaxis=dict(title=dict(text="signed deviation [mm] (+ material added, − missing)"),
                   range=[-span, span]),
        yaxis=dict(title=dict(text="points")), bargap=0.02, height=380, barmode="stack",
        margin=dict(l=60, r=20, t=50, b=50), showlegend=True,
        legend=dict(orientation="h", yanchor="bottom", y=0.9, x=0.0),
        title=dict(text=f"Histogram of {v.size:,} evaluated deviations{note}", x=0.5,
                   font=dict(size=14)))
    return fig


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d1d1f;background:#f6f7f9}
main{max-width:1200px;margin:0 auto;padding:16px 24px 48px}
.banner{color:#fff;padding:18px 24px;border-radius:8px;margin:12px 0}
.banner h1{margin:0;font-size:28px;letter-spacing:.04em}
.banner ul{margin:8px 0 0 18px;padding:0}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(320px,1fr));gap:16px}
.card{background:#fff;border-radius:8px;padding:12px 16px;box-shadow:0 1px 3px rgba(0,0,0,.08);margin-top:16px}
h2{font-size:17px;margin:4px 0 10px}
table{border-collapse:collapse;font-size:14px}
td,th{padding:3px 10px;border-bottom:1px solid #e5e5e5;text-align:right}
td:first-child,th:first-child{text-align:left}
table.chars td:nth-child(2){text-align:left}
tr.drf th{background:#eef0f3;text-align:left;padding-top:6px}
.note{color:#555;font-size:13px}
@page{size:A4 portrait;margin:12mm}
@media print{body{background:#fff}main{max-width:none;padding:0}.card{box-shadow:none;
break-inside:auto}table.chars tr{break-inside:avoid}}
@media print,(max-width:860px){main{padding:8px}table.chars{font-size:10px}
table.chars td,table.chars th{padding:2px 3px}table.chars .fcf,table.chars .fcf-comp{font-size:11px}}
"""


_PLOTLY_LOADER = """<script id="sv-plotly-gz" type="application/octet-stream">{b64}</script>
<script>
// plotly.js {version}, gzip-compressed in this file (1.5 MB instead of 4.8 MB), unpacked here by
// the browser (DecompressionStream); the figures are drawn once it is loaded
window.svPlotly = (async function () {{
  var b64 = document.getElementById("sv-plotly-gz").textContent;
  var bytes = Uint8Array.from(atob(b64), function (c) {{ return c.charCodeAt(0); }});
  var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
  var code = await new Response(stream).text();
  var tag = document.createElement("script");
  tag.textContent = code;
  document.head.appendChild(tag);
  return window.Plotly;
}})();
</script>"""

_PLOTLY_CACHE: dict = {}


def _plotly_loader() -> str:
    """The ``<script>`` elements that carry plotly.js (gzip, base64) and unpack it: a report
    of a 40,000-point scan was 6-7 MB, 4.8 MB of it plotly.js (issue 32)."""
    if "html" not in _PLOTLY_CACHE:
        import base64
        import gzip

        from plotly.offline import get_plotlyjs, get_plotlyjs_version

        packed = gzip.compress(get_plotlyjs().encode("utf-8"), compresslevel=9, mtime=0)
        _PLOTLY_CACHE["html"] = _PLOTLY_LOADER.format(
            b64=base64.b64encode(packed).decode("ascii"), version=get_plotlyjs_version())
    return _PLOTLY_CACHE["html"]


def _after_plotly(div: str) -> str:
    """A figure's ``<div>`` from ``plotly.io.to_html`` whose drawing script waits for the
    packed plotly.js (:func:`_plotly_loader`)."""
    import re

    def wait(m):
        return f"{m.group(1)}window.svPlotly.then(function () {{{m.group(2)}}});</script>"

    out, n = re.subn(r"(<script[^>]*>)(.*?)</script>", wait, div, flags=re.S)
    if n != 1:
        raise RuntimeError(f"plotly's figure HTML changed: {n} scripts where one was expected")
    return out


def render_html(result, model=None, *, max_points: int = MAX_POINTS, title: str | None = None,
                rng=0) -> str:
    """The report as one HTML string (see :func:`write_html_report`)."""
    import plotly.io as pio

    rng = generator(rng)
    d = result.to_dict()
    tol = result.tolerance
    c_lim = color_limit(tol)
    idx, subsampled = _subsample(result, max_points, rng)
    fig3d = _figure_3d(result, model, idx, c_lim)
    fighist = _figure_hist(result, c_lim)
    cfg = {"displaylogo": False, "responsive": True}
    div3d = _after_plotly(pio.to_html(fig3d, full_html=False, include_plotlyjs=False,
                                      div_id="view3d", config=cfg))
    divhist = _after_plotly(pio.to_html(fighist, full_html=False, include_plotlyjs=False,
                                        div_id="histogram", config=cfg))

    verdict = result.verdict
    reasons = "".join(f"<li>{html.escape(r)}</li>" for r in result.reasons)
    source = html.escape(str(getattr(model, "source", "") or ""))
    title = title or f"Shape inspection: {verdict_style(verdict).word}"
    s = d["deviation"]
    stats_rows = [
        ("evaluated points", _fmt(s["n"])), ("mean [mm]", _fmt(s["mean"], signed=True)),
        ("std [mm]", _fmt(s["std"])), ("RMS [mm]", _fmt(s["rms"])),
        ("min [mm]", _fmt(s["min"], signed=True)), ("max [mm]", _fmt(s["max"], signed=True)),
        ("p05 [mm]", _fmt(s["p05"], signed=True)), ("p95 [mm]", _fmt(s["p95"], signed=True)),
        ("in tolerance", "–" if s["in_tolerance_fraction"] is None
         else f"{100 * s['in_tolerance_fraction']:.2f} %"),
        ("above upper / below lower", f"{s['n_above']:,} / {s['n_below']:,}"),
    ]
    ex = d.get("excluded") or {}
    cov = d.get("coverage")
    inp = d.get("inputs") or {}
    tol_text = (f"±{tol.upper:.4g} mm" if tol.lower == -tol.upper
                else f"[{tol.lower:+.4g}, {tol.upper:+.4g}] mm")
    dec = d.get("decision") or {}
    input_rows = [
        ("part", html.escape(str(inp.get("part") or "–"))),
        ("scan file", html.escape(str(inp.get("scan") or "–"))),
        ("model file", html.escape(str(inp.get("model") or source or "–"))),
        ("decided by rule", html.escape(str(dec.get("rule") or "–"))),
        ("tolerance", tol_text + (f" ({len(tol.per_face)} face overrides)" if tol.per_face else "")),
        ("coverage", "–" if not cov else
         f"{100 * cov['fraction']:.1f} % of {cov['area_mm2']:,.0f} mm² (at least "
         f"{100 * cov['min_coverage']:.0f} % needed)"),
        ("scan points", _fmt(d["n_points"])),
        ("excluded: too far", f"{ex.get('too_far', 0):,} (> {_fmt(d['evaluation_distance'], 3)} mm, "
                              "the evaluation distance)"),
        ("excluded: in material regions", f"{ex.get('material', 0):,}"),
        ("excluded: past the CAD's edges", f"{ex.get('on_boundary', 0):,}"),
        ("excluded: on faces not inspected", f"{ex.get('outside_faces', 0):,}"),
        ("excluded: measurement outliers", f"{d['outliers']['n']:,} ({d['outliers']['n_low_weight']:,} "
                                           "rejected by the registration)"),
        ("point spacing [mm]", _fmt(d.get("scan_spacing", d.get("spacing")), 3)),
    ]
    r, fit = d["registration"], d.get("fit") or {}
    fi = fit.get("inlier_fraction")
    reg_rows = [("converged", _fmt(r["converged"])), ("iterations", _fmt(r["iterations"])),
                ("RMS of the evaluated inliers [mm]", _fmt(fit.get("rms"))),
                ("inlier fraction", "–" if fi is None else f"{100 * fi:.1f} %"),
                ("inliers are", html.escape(fit.get("rule", ""))),
                ("registration's robust RMS [mm] / weights' inliers",
                 f"{_fmt(r['rms'])} / " + ("–" if r["inlier_fraction"] is None
                                          else f"{100 * r['inlier_fraction']:.1f} %"))]
    if r.get("message"):
        reg_rows.append(("message", html.escape(r["message"])))
    T = np.asarray(d["T_model_scan"])
    t_html = "<pre>" + "\n".join(" ".join(f"{x:+.6f}" for x in row) for row in T) + "</pre>"
    if result.regions:
        reg_tab = _table(
            [(f"R{i + 1}", g.kind, _fmt(g.n), area_text(g.area), _length(g.extreme),
              _length(g.extreme_raw), _fmt(g.severity, 3),
              ", ".join(f"{c:.2f}" for c in g.centroid),
              html.escape(", ".join(str(f) for f in g.faces[:10])), g.side)
             for i, g in enumerate(result.regions)],
            header=("region", "kind", "points", "area", "extreme", "largest single",
                    "severity [mm³]", "centroid x, y, z [mm]", "faces", "side"), cls="regions")
    else:
        reg_tab = ('<p class="note">No regions: no connected out-of-tolerance surface, no '
                   'material where the CAD has none and none missing where it has some.</p>')
    chars = d.get("characteristics") or []
    char_card = ""
    if chars:
        from shapeverify.characteristics.evaluate import format_value

        def _fmt_char(v, signed=False):
            return format_value(v, signed, sep="<br>", escape=html.escape)

        char_tab = _characteristics_table(chars, result.plan, _fmt_char)
        al = d.get("alignment") or {}
        char_card = (f'<div class="card"><h2>Characteristics (mm)</h2><p class="note">Alignment: '
                     f'{html.escape(str(al.get("type", "–")))}, rms {_fmt(al.get("rms"), 4)} mm. '
                     'Verdicts by the ISO 14253-1 decision rule: a value conforms only when it lies '
                     'inside the limits by more than its uncertainty U, fails only when outside by '
                     'more than U; otherwise it is undecided. A zone read from extreme points '
                     '(flatness, orientation, form, runout) has the scan noise\'s expected part '
                     'taken off: "points 0.15 − noise 0.11" under its value.</p>' + char_tab + '</div>')
    pf = sorted(result.per_face.items(), key=lambda kv: kv[1].in_tolerance_fraction)
    pf_tab = _table(
        [(str(f), _fmt(st.n), _fmt(st.mean, 4, True), _fmt(st.std), _fmt(st.min, 4, True),
          _fmt(st.max, 4, True), f"{100 * st.in_tolerance_fraction:.2f} %") for f, st in pf],
        header=("face", "points", "mean [mm]", "std [mm]", "min [mm]", "max [mm]", "in tolerance"),
        cls="perface")
    timings = " · ".join(f"{html.escape(k)} {v:.3f} s" for k, v in result.timings.items())
    sub_note = (f"The 3D view shows {idx.size:,} of {result.deviations.n_evaluated:,} evaluated points "
                "(all out-of-tolerance points and a random sample of the others); statistics and "
                "the histogram use every point." if subsampled else
                f"The 3D view shows all {idx.size:,} evaluated points.")
    now = _dt.datetime.now().astimezone().isoformat(timespec="seconds")
    try:
        from importlib.metadata import version
        sv_version = version("shapeverify")
    except Exception:  # pragma: no cover - not installed as a distribution
        sv_version = "?"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{html.escape(title)}</title><style>{_CSS}{FCF_CSS}</style>
{_plotly_loader()}</head>
<body><main>
<div class="banner" id="verdict" style="background:{verdict_style(verdict).colour}">
<h1>{html.escape(verdict_style(verdict).word)}</h1>
<div>part {html.escape(str(inp.get('part') or '–'))} · scan {html.escape(str(inp.get('scan') or '–'))} ·
tolerance {html.escape(tol_text)} · {_fmt(s['n'])} evaluated points · rule {html.escape(str(dec.get('rule') or '–'))} · all lengths in mm</div>
{f'<ul>{reasons}</ul>' if reasons else ''}</div>
<div class="grid">
<div class="card"><h2>Deviation statistics (mm)</h2>{_table(stats_rows)}</div>
<div class="card"><h2>Inspection</h2>{_table(input_rows)}</div>
<div class="card"><h2>Registration</h2>{_table(reg_rows)}
<div class="note">T_model_scan (model = R · scan + t, mm):</div>{t_html}</div>
</div>
<div class="card"><h2>3D view: scan coloured by deviation from CAD (mm)</h2><p class="note">{sub_note} Colours: blue = material missing,
red = material added, clipped at ±{c_lim:.3g} mm (2 × tolerance). Grey surface: CAD model; grey
dots: CAD area the scan did not see (no evaluated points near it).
Drag to rotate, scroll to zoom; click legend entries to show or hide layers.</p>{div3d}</div>
<div class="card"><h2>Histogram</h2>{divhist}</div>
{char_card}
<div class="card"><h2>Regions (most severe first)</h2><p class="note">"deviation": connected
out-of-tolerance surface; "extreme" is the deviation at its worst point taken from the point's
neighbourhood (always beyond the limit), "largest single" the most extreme measured point.
"material": measured surface where the CAD has none (e.g. a hole not pierced); "extreme" is its
largest distance from the CAD. "missing": CAD surface the scan sees through, enclosed by seen surface
(a hole the CAD does not have); its area is the CAD area seen through, it has no extreme. Severity: the out-of-tolerance volume (mm³), which orders the
regions. Positions in model coordinates (mm).</p>{reg_tab}</div>
<div class="card"><details><summary><b>Per-face statistics</b> ({len(pf)} faces, worst first)</summary>
{pf_tab}</details></div>
<p class="note">Model: {source or '–'} · generated {now} by shapeverify {html.escape(sv_version)}
· timings: {timings} · units: mm</p>
</main></body></html>
"""


def html_report(result, prep=None, scan=None, *, max_points: int = MAX_POINTS,
                title: str | None = None, rng=0) -> bytes:
    """The self-contained HTML report of an inspection, as UTF-8 bytes.

    Parameters
    ----------
    result : InspectionResult
    prep : Prepared or Model, optional
        Its model (``prep.model``, or ``prep`` itself if it is a model) is drawn as the grey CAD
        surface; omitted for point-cloud models or when None.
    scan : (N, 3) array_like, optional
        The scan as passed to ``inspect``; only its length is checked (the report draws
        ``result.deviations.points_model``).
    max_points : int
        Largest number of points in the 3D view (default :data:`MAX_POINTS`, 20,000: all
        out-of-tolerance points and a random sample of the others; the histogram and the
        statistics use every point).
    title : str, optional
    rng : seed for the subsampling (repeatable by default).

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        If ``scan`` does not have as many points as the inspection, or ``max_points < 1``.
    """
    if max_points < 1:
        raise ValueError(f"max_points must be >= 1, got {max_points}")
    check_scan_length(result, scan)
    model = getattr(prep, "model", prep)
    return render_html(result, model, max_points=max_points, title=title, rng=rng).encode("utf-8")


def write_html_report(result, prep=None, scan=None, path="report.html", *,
                      max_points: int = MAX_POINTS, title: str | None = None, rng=0) -> Path:
    """Write :func:`html_report` to ``path`` (str or Path); parameters and errors as there.

    Returns
    -------
    pathlib.Path
    """
    data = html_report(result, prep, scan, max_points=max_points, title=title, rng=rng)
    path = Path(path)
    path.write_bytes(data)
    logger.info("HTML report written to %s (%.1f MB)", path, len(data) / 1e6)
    return path
