"""Inspection history in an embedded SQLite database, and trend charts for process control.

Every inspection stored with :meth:`HistoryDB.add` becomes one row of the table ``inspections``:
part id, ISO-8601 time, model hash (the SHA-256 of the model file), verdict, the overall
statistics of the evaluated inliers (n, mean, std, rms, signed min and max, p05, p95,
in_tolerance_fraction), their largest ``|d|`` (``max_abs``), the most negative and most positive
region extreme (``region_min``, ``region_max``; NULL without regions on that side), the
tolerance limits (``lower``, ``upper``), the number of regions, ``T_model_scan`` (JSON) and the
full JSON summary of the result.  The database runs in WAL mode, so a reader (``shapeverify
history``) never blocks the production line writing to it; each ``add`` is one transaction.
A database of an earlier schema is migrated when opened (the new columns are added and filled
from each row's stored JSON).

Records of different models never share a chart: :meth:`HistoryDB.query` selects one model
(``model=``: its SHA-256 or a unique prefix of it), :meth:`HistoryDB.models` lists them, and
:func:`plot_trend` refuses rows of several models.

:func:`plot_trend` draws, per inspection, the signed min and max of the deviations against both
tolerance limits (a -0.5 mm dent is as visible as a +0.5 mm bump; the region extremes too), then
mean and ``max |d|`` as Shewhart individuals charts: the centre line is the mean of a *baseline*
and the control limits are ``mean ± 3 sigma`` with sigma the sample standard deviation of that
baseline (the first ``baseline`` records, default: all records shown); a point outside the
limits is drawn red.

References
----------
Montgomery, *Introduction to Statistical Quality Control*, ch. 6 (individuals control charts).
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import math
import sqlite3
from pathlib import Path

import numpy as np

from ..verdict_table import VERDICT_TABLE

logger = logging.getLogger(__name__)

__all__ = ["HistoryDB", "plot_trend", "control_limits", "STAT_COLUMNS"]

SCHEMA_VERSION = 3     # 2: verdict 'incomplete' allowed; 3: max_abs, region extremes, limits
STAT_COLUMNS = ("n", "mean", "std", "rms", "min", "max", "p05", "p95", "in_tolerance_fraction")
#: columns of version 3, filled from the stored JSON when an older database is opened
EXTRA_COLUMNS = ("max_abs", "region_min", "region_max", "lower", "upper")
_V2_COLUMNS = ("id", "part", "time", "model_hash", "verdict") + STAT_COLUMNS + (
    "n_regions", "transform", "result_json")
_ROW_COLUMNS = ("id", "part", "time", "model_hash", "verdict") + STAT_COLUMNS + (
    "n_regions",) + EXTRA_COLUMNS


def _schema() -> str:
    """The table's SQL; its CHECK lists the verdicts of :data:`~shapeverify.verdict_table.VERDICT_TABLE`."""
    verdicts = ", ".join(f"'{v}'" for v in VERDICT_TABLE)
    return f"""
CREATE TABLE IF NOT EXISTS inspections (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    part TEXT,
    time TEXT NOT NULL,
    model_hash TEXT,
    verdict TEXT NOT NULL CHECK (verdict IN ({verdicts})),
    {", ".join(f"{c} {'INTEGER' if c == 'n' else 'REAL'}" for c in STAT_COLUMNS)},
    n_regions INTEGER,
    transform TEXT NOT NULL,
    result_json TEXT NOT NULL,
    {", ".join(f"{c} REAL" for c in EXTRA_COLUMNS)}
);
CREATE INDEX IF NOT EXISTS inspections_part ON inspections (part, id);
CREATE INDEX IF NOT EXISTS inspections_model ON inspections (model_hash, id);
"""


def _sql_num(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _extras(d: dict) -> list:
    """Values of :data:`EXTRA_COLUMNS` from a result's JSON summary: the largest |d| of the
    evaluated inliers, the most negative / most positive region extreme, the limits."""
    dev = d.get("deviation") or {}
    lo, hi = _sql_num(dev.get("min")), _sql_num(dev.get("max"))
    ends = [abs(v) for v in (lo, hi) if v is not None]
    ext = [_sql_num(r.get("extreme")) for r in d.get("regions") or []]
    neg = [v for v in ext if v is not None and v < 0]
    pos = [v for v in ext if v is not None and v > 0]
    tol = d.get("tolerance") or {}
    return [max(ends) if ends else None, min(neg) if neg else None, max(pos) if pos else None,
            _sql_num(tol.get("lower")), _sql_num(tol.get("upper"))]


def _row(result, part, model_hash, time) -> tuple[dict, tuple, list]:
    """(result dict, column names, values) of one history row (``result``: an inspection
    result, or its ``to_dict()`` as a front end extended it)."""
    d = dict(result) if isinstance(result, dict) else result.to_dict()
    if time is None:
        time = _dt.datetime.now().astimezone()
    stamp = time.isoformat(timespec="seconds") if isinstance(time, _dt.datetime) else str(time)
    dev = d.get("deviation", {})
    values = ([part, stamp, model_hash, d["verdict"]]
              + [_sql_num(dev.get(c)) for c in STAT_COLUMNS]
              + [len(d.get("regions", [])), json.dumps(d["T_model_scan"]), json.dumps(d)]
              + _extras(d))
    cols = ("part", "time", "model_hash", "verdict") + STAT_COLUMNS + (
        "n_regions", "transform", "result_json") + EXTRA_COLUMNS
    return d, cols, values


class HistoryDB:
    """SQLite history of inspections.

    Parameters
    ----------
    path : str or Path
        Database file (created with its table if missing).

    Raises
    ------
    ValueError
        If the file exists but is not an SQLite database, or its schema is newer than this
        version of shapeverify understands.

    Examples
    --------
    >>> import shapeverify as sv
    >>> from shapeverify.cad.examples import wavy_panel
    >>> from shapeverify.simulate import virtual_scan
    >>> prep = sv.prepare(wavy_panel(), spacing=2.0)
    >>> result = sv.inspect(prep, virtual_scan(prep, pixel=2.0, rng=1).scan, tolerance=0.2)
    >>> with HistoryDB("history.sqlite") as db:      # a new file in the working directory
    ...     rid = db.add(result, part="A-0017", model_hash="(file_hash of the model file)")
    ...     rows = db.query(part="A-0017", limit=50)
    >>> [(r["part"], r["verdict"]) for r in rows]
    [('A-0017', 'pass')]
    """

    def __init__(self, path):
        self.path = Path(path)
        self._con = sqlite3.connect(str(self.path), timeout=30.0)
        self._con.row_factory = sqlite3.Row
        try:
            mode = self._con.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        except sqlite3.DatabaseError as exc:
            self._con.close()
            raise ValueError(f"{self.path}: not an SQLite history database ({exc})") from None
        if str(mode).lower() != "wal":  # pragma: no cover - e.g. a network file system
            logger.warning("%s: SQLite WAL mode unavailable (journal_mode=%s)", self.path, mode)
        self._con.execute("PRAGMA synchronous=NORMAL")
        # the version check and any migration in one write transaction: two processes opening
        # an old file at once (service workers) migrate it once
        self._con.execute("BEGIN IMMEDIATE")
        try:
            version = self._con.execute("PRAGMA user_version").fetchone()[0]
            if version > SCHEMA_VERSION or version < 0:
                raise ValueError(f"{self.path}: history schema version {version} is newer than "
                                 f"this shapeverify understands ({SCHEMA_VERSION})")
            if version == 1:
                self._migrate_v1()
            else:
                self._add_columns(version)
            self._create()
            self._allow_table_verdicts()
            self._con.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            self._con.commit()
        except BaseException:
            self._con.rollback()
            self._con.close()
            raise

    def _create(self) -> None:
        """The table and indexes if missing (statement by statement: ``executescript`` would
        commit the open transaction)."""
        for stmt in _schema().split(";"):
            if stmt.strip():
                self._con.execute(stmt)

    def _migrate_v1(self) -> None:
        """Version 1 refused the verdict 'incomplete' (a CHECK constraint): copy the rows into
        a table of the current schema (SQLite cannot alter a constraint in place)."""
        self._con.execute("ALTER TABLE inspections RENAME TO inspections_v1")
        self._con.execute("DROP INDEX IF EXISTS inspections_part")
        self._create()
        cols = ", ".join(_V2_COLUMNS)
        self._con.execute(f"INSERT INTO inspections ({cols}) SELECT {cols} FROM inspections_v1")
        self._con.execute("DROP TABLE inspections_v1")
        self._fill_extras()
        logger.info("%s: history upgraded from schema version 1 to %d", self.path, SCHEMA_VERSION)

    def _allow_table_verdicts(self) -> None:
        """A file made before a verdict value was added to
        :data:`~shapeverify.verdict_table.VERDICT_TABLE` refuses it (its CHECK lists the values
        of then): copy the rows into a table of the current schema (SQLite cannot alter a
        constraint in place), as :meth:`_migrate_v1` does."""
        row = self._con.execute("SELECT sql FROM sqlite_master WHERE type = 'table' AND "
                                "name = 'inspections'").fetchone()
        if row is None or all(f"'{v}'" in row[0] for v in VERDICT_TABLE):
            return
        self._con.execute("ALTER TABLE inspections RENAME TO inspections_old")
        self._con.execute("DROP INDEX IF EXISTS inspections_part")
        self._con.execute("DROP INDEX IF EXISTS inspections_model")
        self._create()
        cols = ", ".join(_V2_COLUMNS + EXTRA_COLUMNS)
        self._con.execute(f"INSERT INTO inspections ({cols}) SELECT {cols} FROM inspections_old")
        self._con.execute("DROP TABLE inspections_old")
        logger.info("%s: history now accepts the verdicts %s", self.path,
                    ", ".join(map(str, VERDICT_TABLE)))

    def _add_columns(self, version: int) -> None:
        """Versions 0 (an existing table without a version) and 2: add the columns of version 3
        and fill them from each row's stored JSON."""
        have = {r[1] for r in self._con.execute("PRAGMA table_info(inspections)").fetchall()}
        if not have:        # a new file: the schema creates everything
            return
        missing = [c for c in EXTRA_COLUMNS if c not in have]
        for c in missing:
            self._con.execute(f"ALTER TABLE inspections ADD COLUMN {c} REAL")
        if missing:
            self._fill_extras()
            logger.info("%s: history upgraded from schema version %d to %d", self.path, version,
                        SCHEMA_VERSION)

    def _fill_extras(self) -> None:
        rows = self._con.execute("SELECT id, result_json FROM inspections").fetchall()
        sets = ", ".join(f"{c} = ?" for c in EXTRA_COLUMNS)
        for rid, text in rows:
            try:
                d = json.loads(text)
            except (TypeError, ValueError):
                continue    # an unreadable summary: the new columns stay NULL
            self._con.execute(f"UPDATE inspections SET {sets} WHERE id = ?",
                              _extras(d if isinstance(d, dict) else {}) + [rid])

    # -- context manager -------------------------------------------------------------------
    def __enter__(self) -> "HistoryDB":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._con.close()

    def __repr__(self) -> str:
        return f"HistoryDB({str(self.path)!r})"

    # -- writing ---------------------------------------------------------------------------
    def add(self, result, part: str | None = None, model_hash: str | None = None,
            time: _dt.datetime | str | None = None) -> int:
        """Store one inspection result in one transaction; return its id.

        Parameters
        ----------
        result : InspectionResult, or a dict (its ``to_dict()``, with ``verdict``,
            ``deviation``, ``T_model_scan`` and ``regions``) as a front end extended it
        part : str, optional
            Part id (serial number).
        model_hash : str, optional
            Hash of the model file (e.g. :func:`shapeverify.pipeline.file_hash`).
        time : datetime or ISO string, optional
            Default: now (local time with UTC offset).
        """
        d, cols, values = _row(result, part, model_hash, time)
        with self._con:      # one transaction: committed on success, rolled back on error
            cur = self._con.execute(
                f"INSERT INTO inspections ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})",
                values)
        logger.info("history: stored inspection %d (%s, part %s)", cur.lastrowid, d["verdict"], part)
        return int(cur.lastrowid)

    def replace(self, record_id: int, result, part: str | None = None,
                model_hash: str | None = None, time: _dt.datetime | str | None = None) -> int:
        """Overwrite record ``record_id`` with a new result (same id), in one transaction.

        For a result that supersedes the stored one -- e.g. a batch scan inspected again
        (``batch --retry-errors``): the part keeps one row instead of gaining a second.
        Parameters as for :meth:`add`.

        Raises
        ------
        KeyError
            If there is no record with this id (nothing is written).
        """
        d, cols, values = _row(result, part, model_hash, time)
        with self._con:
            cur = self._con.execute(
                f"UPDATE inspections SET {', '.join(c + ' = ?' for c in cols)} WHERE id = ?",
                values + [int(record_id)])
        if cur.rowcount != 1:
            raise KeyError(f"{self.path}: no inspection record with id {record_id} to replace")
        logger.info("history: replaced inspection %d (%s, part %s)", record_id, d["verdict"], part)
        return int(record_id)

    # -- reading ---------------------------------------------------------------------------
    def query(self, part: str | None = None, limit: int | None = 100,
              verdict: str | None = None, model: str | None = None) -> list[dict]:
        """The most recent ``limit`` records (oldest first), optionally of one part / verdict /
        model.

        Parameters
        ----------
        model : str, optional
            The model's SHA-256 (hex), or a prefix of it that only one stored model has.

        Returns
        -------
        list of dict
            Keys: id, part, time, model_hash, verdict, n, mean, std, rms, min, max, p05, p95,
            in_tolerance_fraction, n_regions, max_abs, region_min, region_max, lower, upper
            (numbers NaN where not available).

        Raises
        ------
        ValueError
            If ``model`` matches no stored model or several (the message lists them).
        """
        where, args = [], []
        if model is not None:
            where.append("model_hash = ?")
            args.append(self.resolve_model(model))
        if part is not None:
            where.append("part = ?")
            args.append(part)
        if verdict is not None:
            where.append("verdict = ?")
            args.append(verdict)
        sql = f"SELECT {', '.join(_ROW_COLUMNS)} FROM inspections"
        if where:
            sql += " WHERE " + " AND ".join(where)
        sql += " ORDER BY id DESC"
        if limit is not None:
            if int(limit) < 1:
                raise ValueError(f"limit must be >= 1 (or None for all), got {limit}")
            sql += f" LIMIT {int(limit)}"
        rows = [dict(r) for r in self._con.execute(sql, args).fetchall()]
        for r in rows:
            for c in STAT_COLUMNS[1:] + EXTRA_COLUMNS:
                if r[c] is None:
                    r[c] = float("nan")
        return rows[::-1]

    def models(self) -> list[dict]:
        """The models in the history, most recently inspected last: ``model_hash``, ``n``
        (records), ``name`` (the model name or file the last record gives, if any), ``last``
        (time of the last record)."""
        out = []
        for h, n, last_id, last in self._con.execute(
                "SELECT model_hash, COUNT(*), MAX(id), MAX(time) FROM inspections "
                "GROUP BY model_hash ORDER BY MAX(id)").fetchall():
            text = self._con.execute("SELECT result_json FROM inspections WHERE id = ?",
                                     (last_id,)).fetchone()[0]
            try:
                d = json.loads(text)
                name = d.get("model") or (d.get("inputs") or {}).get("model")
            except (TypeError, ValueError, AttributeError):
                name = None
            out.append({"model_hash": h, "n": int(n), "name": name, "last": last})
        return out

    def resolve_model(self, model: str) -> str:
        """The stored model hash that ``model`` (a SHA-256 or a prefix of one) names.

        Raises
        ------
        ValueError
            If no stored model or more than one matches.
        """
        key = str(model).strip().lower()
        hashes = [m["model_hash"] for m in self.models() if m["model_hash"] is not None]
        hits = [h for h in hashes if h.lower() == key] or \
               [h for h in hashes if key and h.lower().startswith(key)]
        if len(hits) == 1:
            return hits[0]
        listed = ", ".join(h[:12] for h in hashes) or "none"
        if not hits:
            raise ValueError(f"{self.path}: no records of model {model!r} (the models stored: "
                             f"{listed}; give a SHA-256 or a prefix of one)")
        raise ValueError(f"{self.path}: {model!r} is the start of {len(hits)} model hashes "
                         f"({', '.join(h[:12] for h in hits)}); give more of it")

    def get(self, record_id: int) -> dict:
        """One full record: the row's fields plus ``T_model_scan`` (4x4 list) and ``result``
        (the stored JSON summary).

        Raises
        ------
        KeyError
            If there is no record with this id.
        """
        r = self._con.execute(
            f"SELECT {', '.join(_ROW_COLUMNS)}, transform, result_json FROM inspections WHERE id = ?",
            (int(record_id),)).fetchone()
        if r is None:
            raise KeyError(f"{self.path}: no inspection record with id {record_id}")
        d = dict(r)
        d["T_model_scan"] = json.loads(d.pop("transform"))
        d["result"] = json.loads(d.pop("result_json"))
        return d

    def __len__(self) -> int:
        return int(self._con.execute("SELECT COUNT(*) FROM inspections").fetchone()[0])


def control_limits(values: np.ndarray, baseline: int | None = None) -> tuple[float, float, float]:
    """``(centre, lower, upper)``: mean ± 3 sample standard deviations of the baseline values.

    The baseline is the first ``baseline`` finite values (all if None). NaN when fewer than 2.
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if baseline is not None:
        v = v[: int(baseline)]
    if v.size < 2:
        return float("nan"), float("nan"), float("nan")
    m, s = float(v.mean()), float(v.std(ddof=1))
    return m, m - 3.0 * s, m + 3.0 * s


def _column(rows, key) -> np.ndarray:
    return np.array([np.nan if r.get(key) is None else float(r[key]) for r in rows])


def _shewhart(ax, x, y, baseline, failed) -> None:
    """An individuals chart of y on ax: centre line, mean ± 3 sigma of the baseline, points
    outside red, failed inspections circled."""
    ax.plot(x, y, "-", color="#4c72b0", linewidth=1, zorder=1)
    c, lo, hi = control_limits(y, baseline)
    out = np.zeros(len(y), bool)
    if np.isfinite(c):
        ax.axhline(c, color="#333333", linewidth=1, label=f"centre {c:+.4f}")
        for lim in (lo, hi):
            ax.axhline(lim, color="#7a5195", linestyle=":", linewidth=1)
        ax.text(1.005, hi, f"UCL {hi:+.4f}", transform=ax.get_yaxis_transform(), fontsize=8,
                va="center", color="#7a5195")
        ax.text(1.005, lo, f"LCL {lo:+.4f}", transform=ax.get_yaxis_transform(), fontsize=8,
                va="center", color="#7a5195")
        with np.errstate(invalid="ignore"):
            out = (y > hi) | (y < lo)
    ok = np.isfinite(y) & ~out
    ax.scatter(x[ok], y[ok], s=18, color="#4c72b0", zorder=2)
    ax.scatter(x[out], y[out], s=30, color="#7a5195", zorder=3, label="outside control limits")
    f = failed & np.isfinite(y)
    ax.scatter(x[f], y[f], s=80, facecolors="none", edgecolors="#b3261e", zorder=4,
               label="verdict fail")


def _limit_steps(ax, x, lim, label) -> None:
    """A tolerance limit per record (it may change between records) as a step line."""
    if np.isfinite(lim).any():
        ax.step(x, lim, where="mid", color="#b3261e", linestyle="--", linewidth=1.2, label=label)


def plot_trend(rows, path, baseline: int | None = None, *, dpi: int = 110) -> Path:
    """Trend charts of one model's inspections: signed min and max against both tolerance
    limits, then mean and max |d| with control limits.

    Parameters
    ----------
    rows : list of dict
        Records as returned by :meth:`HistoryDB.query` (oldest first), all of one model.
    path : str or Path
        PNG file to write.
    baseline : int, optional
        Number of first records that define the control limits (default: all records).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        If there are no rows, rows of several models (choose one: ``query(model=...)``,
        ``shapeverify history --model``), or ``baseline < 2``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = list(rows)
    if not rows:
        raise ValueError("no inspection records to plot")
    hashes = sorted({str(r.get("model_hash")) for r in rows})
    if len(hashes) > 1:
        short = ", ".join(h[:12] for h in hashes)
        raise ValueError(f"the records are of {len(hashes)} models ({short}): one chart shows "
                         "one model; choose it (shapeverify history --model SHA256-PREFIX, or "
                         "HistoryDB.query(model=...))")
    if baseline is not None and int(baseline) < 2:
        raise ValueError(f"baseline must be >= 2 records, got {baseline}")
    x = np.arange(1, len(rows) + 1)
    verdicts = [r.get("verdict") for r in rows]
    failed = np.array([v == "fail" for v in verdicts])
    fig = Figure(figsize=(11, 9.5), dpi=dpi)
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [1.6, 1, 1]})
    base_text = f"first {int(baseline)} records" if baseline else "all records shown"

    # 1. signed min and max against both limits
    ax = axes[0]
    lo, hi = _column(rows, "min"), _column(rows, "max")
    lower, upper = _column(rows, "lower"), _column(rows, "upper")
    ax.vlines(x, lo, hi, color="#9aa5b1", linewidth=2, zorder=1)
    with np.errstate(invalid="ignore"):
        lo_out = lo < lower
        hi_out = hi > upper
    ax.scatter(x[~lo_out], lo[~lo_out], marker="v", s=28, color="#2166ac", zorder=2,
               label="min (material missing)")
    ax.scatter(x[~hi_out], hi[~hi_out], marker="^", s=28, color="#d6604d", zorder=2,
               label="max (material added)")
    ax.scatter(np.r_[x[lo_out], x[hi_out]], np.r_[lo[lo_out], hi[hi_out]], marker="o", s=46,
               color="#b3261e", zorder=3, label="beyond a limit")
    rmin, rmax = _column(rows, "region_min"), _column(rows, "region_max")
    for y in (rmin, rmax):
        ok = np.isfinite(y)
        ax.scatter(x[ok], y[ok], marker="x", s=40, color="#111111", zorder=4,
                   label="region extreme" if y is rmin else None)
    _limit_steps(ax, x, upper, "tolerance limits")
    _limit_steps(ax, x, lower, None)
    ax.axhline(0.0, color="#333333", linewidth=0.6)
    ax.set_ylabel("signed min / max [mm]")
    ax.legend(loc="upper left", fontsize=8, ncol=5)

    # 2. mean, 3. max |d|: individuals charts
    _shewhart(axes[1], x, _column(rows, "mean"), baseline, failed)
    axes[1].set_ylabel("mean deviation [mm]")
    axes[1].legend(loc="upper left", fontsize=8, ncol=4)
    mabs = _column(rows, "max_abs")
    if not np.isfinite(mabs).any():      # rows from before max_abs was stored
        mabs = np.fmax(np.abs(lo), np.abs(hi))
    _shewhart(axes[2], x, mabs, baseline, failed)
    _limit_steps(axes[2], x, np.fmax(np.abs(lower), np.abs(upper)), "largest |limit|")
    axes[2].set_ylabel("max |deviation| [mm]")
    axes[2].legend(loc="upper left", fontsize=8, ncol=5)
    for ax in axes:
        if baseline is not None and int(baseline) < len(rows):
            ax.axvspan(0.5, int(baseline) + 0.5, color="#4c72b0", alpha=0.06, zorder=0)
        ax.grid(alpha=0.3)
    errors = [i + 1 for i, v in enumerate(verdicts) if v in ("error", "incomplete")]
    for xe in errors:
        for ax in axes:
            ax.axvline(xe, color="#a15c00", alpha=0.3, linewidth=3)
    part_labels = [str(r.get("part") or r.get("id")) for r in rows]
    if len(rows) <= 30:
        axes[-1].set_xticks(x)
        axes[-1].set_xticklabels(part_labels, rotation=45, ha="right", fontsize=8)
    axes[-1].set_xlabel("inspection (part)" + ("; orange bands: verdict error or incomplete"
                                               if errors else ""))
    model = hashes[0][:12] if hashes[0] != "None" else "unknown"
    fig.suptitle(f"Deviations of {len(rows)} inspections of model {model} (mm); control limits: "
                 f"mean ± 3σ of {base_text}", fontsize=11)
    fig.subplots_adjust(left=0.08, right=0.9, top=0.95, bottom=0.1, hspace=0.1)
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path
