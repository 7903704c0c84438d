"""Characteristic history for SPC: SQLite table, Cp/Cpk, run chart, CSV export.

Every characteristic of a :class:`~.evaluate.PlanResult` becomes one row of the table
``characteristics`` in the same SQLite file as the inspection history
(:class:`shapeverify.report.history.HistoryDB`, WAL mode; the table lives beside
``inspections`` and may point at one of its rows with ``inspection_id``).  A compound result
(a hole) gives one series per key, ``NAME.diameter`` and ``NAME.position``.  Every row keeps
its feature control frame as text (``fcf``: ``⌖|Ø0.5Ⓜ|A|B|C``, ``Ø20.000 +0.05/−0.05``;
:mod:`shapeverify.report.fcf`), also in the CSV export; a history written before has the column
added (empty for its old rows).

The charted **value** of a row is the deviation ``measured - nominal`` (diameters, check points)
or the zone value itself (surface profile, flatness, position: one-sided, ``lower`` NULL).

Capability (:func:`capability`, Montgomery ch. 8): with ``sigma_w = MR̄ / 1.128`` (the mean moving
range of consecutive values, the within-process spread of an individuals chart) and ``s`` the
sample standard deviation (overall):
``Cp = (USL - LSL) / (6 sigma_w)``, ``Cpk = min(USL - mean, mean - LSL) / (3 sigma_w)``,
``Pp, Ppk`` the same with ``s``.  One-sided characteristics have no Cp/Pp (None) and
``Cpk = (USL - mean) / (3 sigma_w)``.  Fewer than :data:`MIN_PARTS` (25) values are flagged
``too_few`` (the indices' own uncertainty is then over ±20 %).

Run chart (:func:`plot_run_chart`): values in order, centre line (mean), control limits
``mean ± 3 sigma_w`` (individuals chart), specification limits, verdict-coloured points.
"""
from __future__ import annotations

import csv
import datetime as _dt
import logging
import math
import sqlite3
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import registry

__all__ = ["store_characteristics", "characteristic_rows", "characteristic_names", "capability",
           "Capability", "plot_run_chart", "run_chart_figure", "export_csv", "MIN_PARTS",
           "VERDICT_COLOURS"]

logger = logging.getLogger(__name__)

#: fewer values than this are flagged: capability indices are not reliable
MIN_PARTS = 25
_D2 = 1.128  # d2 for moving ranges of 2
#: zone widths (no lower limit, no Cp): the registry's one-sided types (a hole's position
#: series is named "position" too)
_ONE_SIDED = tuple(dict.fromkeys(registry.one_sided_types() + ("position",)))

_SCHEMA = """
CREATE TABLE IF NOT EXISTS characteristics (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    inspection_id INTEGER,
    part TEXT,
    time TEXT NOT NULL,
    name TEXT NOT NULL,
    type TEXT NOT NULL,
    nominal REAL,
    measured REAL,
    value REAL,
    lower REAL,
    upper REAL,
    uncertainty REAL,
    verdict TEXT NOT NULL,
    fcf TEXT
);
CREATE INDEX IF NOT EXISTS characteristics_name ON characteristics (name, id);
"""
_COLS = ("id", "inspection_id", "part", "time", "name", "type", "nominal", "measured", "value",
         "lower", "upper", "uncertainty", "verdict", "fcf")


def _num(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _connect(db) -> sqlite3.Connection:
    path = getattr(db, "path", db)
    con = sqlite3.connect(str(path), timeout=30.0)
    con.row_factory = sqlite3.Row
    try:
        con.execute("PRAGMA journal_mode=WAL")
        with con:
            con.executescript(_SCHEMA)
            have = {r[1] for r in con.execute("PRAGMA table_info(characteristics)")}
            if "fcf" not in have:        # a history written before the frames (issue 28)
                con.execute("ALTER TABLE characteristics ADD COLUMN fcf TEXT")
    except sqlite3.DatabaseError as exc:
        con.close()
        raise ValueError(f"{path}: not an SQLite history database ({exc})") from None
    return con


def _rows_of(result) -> list[tuple]:
    """One row per series: a characteristic with one value, or one per key of a compound
    result (a hole's ``diameter`` and ``position``: dicts of limits), each with its feature
    control frame's text (:func:`shapeverify.report.fcf.fcf_text`)."""
    from ..report.fcf import fcf_text

    entries = {e.name: e for e in getattr(getattr(result, "plan", None), "characteristics",
                                          None) or ()}
    out = []
    for c in result.characteristics:
        d = c.to_dict()
        entry = entries.get(c.name)
        if isinstance(d["upper"], dict):
            get = lambda k, key: (d[k] or {}).get(key) if isinstance(d[k], dict) else None  # noqa: E731
            for key, hi in d["upper"].items():
                one = key in _ONE_SIDED
                nom = 0.0 if one else get("nominal", key)
                meas = get("deviation" if one else "measured", key)
                out.append((f"{c.name}.{key}", f"{c.type} {key}", nom, meas,
                            get("deviation", key), None if one else get("lower", key), hi,
                            get("uncertainty", key),
                            d["details"].get("verdicts", {}).get(key, c.verdict),
                            fcf_text(c, entry, key)))
        elif d["upper"] is None and c.type == "hole":
            continue          # a hole not measured: neither series has a value (as before)
        else:
            lo = None if c.type in _ONE_SIDED else d["lower"]
            out.append((c.name, c.type, d["nominal"], d["measured"], d["deviation"], lo,
                        d["upper"], d["uncertainty"], c.verdict, fcf_text(c, entry)))
    return out


def store_characteristics(db, result, part: str | None = None,
                          inspection_id: int | None = None, time=None) -> int:
    """Append every characteristic of a PlanResult to the history (one transaction).

    Parameters
    ----------
    db : path or HistoryDB
        The SQLite file (created with the table if missing).
    result : PlanResult
    part : str, optional
        Part id (default: the plan's ``part``).
    inspection_id : int, optional
        Row id of the inspection in ``inspections`` (:meth:`HistoryDB.add`'s return value).
    time : datetime or ISO string, optional
        Default now (local time with offset).

    Returns
    -------
    int
        Number of rows written.
    """
    if time is None:
        time = _dt.datetime.now().astimezone()
    stamp = time.isoformat(timespec="seconds") if isinstance(time, _dt.datetime) else str(time)
    part = part if part is not None else result.plan.part
    rows = [(inspection_id, part, stamp, n, t, _num(a), _num(b), _num(v), _num(lo), _num(hi),
             _num(u), vd, f) for n, t, a, b, v, lo, hi, u, vd, f in _rows_of(result)]
    con = _connect(db)
    try:
        with con:
            con.executemany(f"INSERT INTO characteristics ({', '.join(_COLS[1:])}) VALUES "
                            f"({', '.join('?' * (len(_COLS) - 1))})", rows)
    finally:
        con.close()
    logger.info("history: stored %d characteristic values (part %s)", len(rows), part)
    return len(rows)


def characteristic_names(db) -> list[str]:
    """Names of the characteristic series in the history (sorted)."""
    con = _connect(db)
    try:
        return [r[0] for r in con.execute("SELECT DISTINCT name FROM characteristics ORDER BY name")]
    finally:
        con.close()


def characteristic_rows(db, name: str, part: str | None = None,
                        limit: int | None = None) -> list[dict]:
    """The history of one characteristic, oldest first.

    ``name`` may be a hole's name (both its series) or a series (``H1.diameter``).

    Raises
    ------
    KeyError
        No such characteristic in the history (the message lists the names there are).
    """
    con = _connect(db)
    try:
        sql = f"SELECT {', '.join(_COLS)} FROM characteristics WHERE (name = ? OR name LIKE ?)"
        args = [name, name.replace("%", "") + ".%"]
        if part is not None:
            sql += " AND part = ?"
            args.append(part)
        sql += " ORDER BY id DESC"
        if limit is not None:
            sql += f" LIMIT {int(limit)}"
        rows = [dict(r) for r in con.execute(sql, args).fetchall()][::-1]
        if not rows:
            have = [r[0] for r in con.execute("SELECT DISTINCT name FROM characteristics")]
            raise KeyError(f"no characteristic {name!r} in the history; it has: "
                           f"{', '.join(sorted(have)) or 'none'}")
        return rows
    finally:
        con.close()


@dataclass(frozen=True)
class Capability:
    """Capability of a series against its specification limits (see the module docstring).

    n, mean, sigma_within (MR̄/1.128), sigma_overall (sample std), cp, cpk, pp, ppk (None when
    not defined), lower, upper, too_few (n < MIN_PARTS), message.
    """

    n: int
    mean: float
    sigma_within: float
    sigma_overall: float
    cp: float | None
    cpk: float | None
    pp: float | None
    ppk: float | None
    lower: float | None
    upper: float | None
    too_few: bool
    message: str

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _div(a, b):
    return None if a is None or not b > 0 else float(a / b)


def capability(values, lower: float | None, upper: float | None) -> Capability:
    """Cp, Cpk, Pp, Ppk of values (n,) against limits (None: that side is open).

    Raises
    ------
    ValueError
        Fewer than 2 finite values, or no limit at all.
    """
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if v.size < 2:
        raise ValueError(f"capability needs at least 2 values, got {v.size}")
    if lower is None and upper is None:
        raise ValueError("capability needs at least one specification limit")
    m = float(v.mean())
    sw = float(np.mean(np.abs(np.diff(v))) / _D2)
    so = float(v.std(ddof=1))
    two = lower is not None and upper is not None
    cp = _div(upper - lower, 6 * sw) if two else None
    pp = _div(upper - lower, 6 * so) if two else None
    sides_w = [x for x in ((None if upper is None else upper - m),
                           (None if lower is None else m - lower)) if x is not None]
    cpk = _div(min(sides_w), 3 * sw)
    ppk = _div(min(sides_w), 3 * so)
    few = v.size < MIN_PARTS
    msg = (f"only {v.size} parts: capability indices need at least {MIN_PARTS} to be reliable"
           if few else f"{v.size} parts")
    return Capability(int(v.size), m, sw, so, cp, cpk, pp, ppk, lower, upper, few, msg)


def _series(rows):
    names = sorted({r["name"] for r in rows})
    return [(n, [r for r in rows if r["name"] == n]) for n in names]


#: the colour of a run chart's point by the part's verdict for the characteristic
VERDICT_COLOURS = {"pass": "#4c72b0", "fail": "#b3261e", "undecided": "#a15c00"}


def plot_run_chart(rows, path, *, dpi: int = 110) -> Path:
    """Run chart(s) of characteristic rows (one panel per series) with control and
    specification limits, the feature control frame and Cp/Cpk in the title; writes a PNG.

    Raises
    ------
    ValueError
        No rows.
    """
    fig = run_chart_figure(rows, dpi=dpi)
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path


def run_chart_figure(rows, *, dpi: int = 110):
    """The figure :func:`plot_run_chart` writes.  Each panel's legend names every verdict
    colour its points use (pass, fail, undecided: issue 32 item 4, the undecided point had no
    entry), the mean, the control limits and the specification limits drawn.

    Raises
    ------
    ValueError
        No rows.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.lines import Line2D
    from matplotlib.figure import Figure

    from ..report.fcf import font_text     # the font lacks some symbols: abbreviations

    rows = list(rows)
    if not rows:
        raise ValueError("no characteristic values to plot")
    series = _series(rows)
    fig = Figure(figsize=(11, 3.6 * len(series) + 0.6), dpi=dpi)
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(len(series), 1))
    for ax, (name, rs) in zip(axes, series):
        y = np.array([np.nan if r["value"] is None else r["value"] for r in rs], float)
        x = np.arange(1, len(y) + 1)
        lo, hi = rs[-1]["lower"], rs[-1]["upper"]
        ax.plot(x, y, "-", color="#4c72b0", lw=1)
        col = VERDICT_COLOURS
        ax.scatter(x, y, s=20, c=[col.get(r["verdict"], "black") for r in rs], zorder=3)
        drawn = [v for v in (*col, *sorted({str(r["verdict"]) for r in rs} - set(col)))
                 if any(str(r["verdict"]) == v for r, yv in zip(rs, y) if np.isfinite(yv))]
        handles = [Line2D([], [], ls="", marker="o", markersize=5, label=v,
                          markerfacecolor=col.get(v, "black"), markeredgecolor=col.get(v, "black"))
                   for v in drawn]
        fcf = rs[-1].get("fcf")
        title = name + (f"  {font_text(fcf)}" if fcf else "")
        if np.isfinite(y).sum() >= 2:
            cap = capability(y, lo, hi)
            ax.axhline(cap.mean, color="#333333", lw=1)
            for lim in (cap.mean - 3 * cap.sigma_within, cap.mean + 3 * cap.sigma_within):
                ax.axhline(lim, color="#b3261e", ls="--", lw=1)
            handles += [Line2D([], [], color="#333333", lw=1, label="mean"),
                        Line2D([], [], color="#b3261e", ls="--", lw=1, label="control limits")]
            f = (lambda v: "-" if v is None else f"{v:.2f}")
            title += (f": Cp {f(cap.cp)}, Cpk {f(cap.cpk)} (Pp {f(cap.pp)}, Ppk {f(cap.ppk)}); "
                      f"control limits mean ± 3 MR̄/1.128")
            if cap.too_few:
                title += f"  [!] {cap.message}"
        for lim, lab in ((lo, "LSL"), (hi, "USL")):
            if lim is not None:
                ax.axhline(lim, color="#1b7f3b", lw=1.5)
                ax.text(1.005, lim, lab, transform=ax.get_yaxis_transform(), fontsize=8,
                        color="#1b7f3b", va="center")
        if lo is not None or hi is not None:
            handles.append(Line2D([], [], color="#1b7f3b", lw=1.5,
                                  label="specification limits"))
        ax.legend(handles=handles, loc="best", fontsize=7, ncol=len(handles), framealpha=0.85)
        ax.set_title(title, fontsize=9)
        ax.set_ylabel("value [mm]")
        ax.grid(alpha=0.3)
        if len(rs) <= 30:
            ax.set_xticks(x)
            ax.set_xticklabels([str(r["part"] or r["id"]) for r in rs], rotation=45,
                               ha="right", fontsize=7)
    axes[-1].set_xlabel("inspection (part)")
    fig.tight_layout()
    return fig


def export_csv(rows, path) -> Path:
    """Write characteristic rows to CSV (columns of the table, one row per value; UTF-8: the
    ``fcf`` column holds the frames' symbols, ⌖ Ⓜ ..., whatever the locale's encoding)."""
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(_COLS))
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in _COLS})
    return path
