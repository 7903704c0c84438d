"""SQLite inspection history (WAL, one transaction per record) and trend charts."""

from __future__ import annotations

import datetime as dt
import json
import sqlite3

import numpy as np
import pytest

from shapeverify.report.history import HistoryDB, control_limits, plot_trend


class FakeResult:
    """Anything with ``to_dict()`` in the InspectionResult JSON shape can be stored."""

    def __init__(self, verdict="pass", mean=0.01, p95=0.05, mx=0.1, n=1000, shift=0.0):
        T = np.eye(4)
        T[:3, 3] = [1.0, 2.0, 3.0 + shift]
        self.d = {
            "verdict": verdict, "reasons": [], "units": "mm", "T_model_scan": T.tolist(),
            "registration": {"rms": 0.02, "iterations": 7, "converged": True, "inlier_fraction": 0.98},
            "deviation": {"n": n, "mean": mean, "std": 0.03, "rms": 0.031, "min": -0.1, "max": mx,
                          "p05": -0.04, "p95": p95, "in_tolerance_fraction": 0.999},
            "tolerance": {"lower": -0.2, "upper": 0.2}, "regions": [], "timings": {"total": 0.1},
        }

    def to_dict(self):
        return json.loads(json.dumps(self.d))


def test_add_get_query_roundtrip(tmp_path):
    path = tmp_path / "h.sqlite"
    with HistoryDB(path) as db:
        t0 = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.timezone.utc)
        ids = [db.add(FakeResult(mean=0.01 * i, shift=i), part=f"P{i:03d}", model_hash="abc",
                      time=t0 + dt.timedelta(minutes=i)) for i in range(5)]
        assert ids == sorted(ids) and len(db) == 5
        rec = db.get(ids[2])
        assert rec["part"] == "P002" and rec["verdict"] == "pass" and rec["model_hash"] == "abc"
        assert rec["time"] == "2026-01-02T03:06:05+00:00"
        assert rec["mean"] == pytest.approx(0.02) and rec["n"] == 1000
        assert rec["T_model_scan"][2][3] == 5.0
        assert rec["result"]["registration"]["iterations"] == 7
        rows = db.query(limit=3)
        assert [r["part"] for r in rows] == ["P002", "P003", "P004"]   # most recent 3, oldest first
        assert [r["part"] for r in db.query(part="P001")] == ["P001"]
        assert db.query(verdict="fail") == []
        with pytest.raises(KeyError, match="no inspection record with id 999"):
            db.get(999)
        with pytest.raises(ValueError, match="limit"):
            db.query(limit=0)
    # reopening keeps the data; the database is in WAL mode
    with HistoryDB(path) as db:
        assert len(db) == 5
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    con.close()


def test_missing_statistics_are_nan_and_failed_add_leaves_no_row(tmp_path):
    with HistoryDB(tmp_path / "h.sqlite") as db:
        err = FakeResult(verdict="error", n=0)
        err.d["deviation"].update(mean=None, p95=None, max=None)
        rid = db.add(err, part="E1")
        row = db.query()[0]
        assert row["id"] == rid and row["verdict"] == "error" and np.isnan(row["mean"])
        bad = FakeResult(verdict="maybe")        # violates the verdict CHECK constraint
        with pytest.raises(sqlite3.IntegrityError):
            db.add(bad, part="X")
        assert len(db) == 1                      # the transaction was rolled back


def test_a_second_connection_reads_while_another_writes(tmp_path):
    path = tmp_path / "h.sqlite"
    with HistoryDB(path) as writer, HistoryDB(path) as reader:
        writer.add(FakeResult(), part="A")
        assert [r["part"] for r in reader.query()] == ["A"]
        writer._con.execute("BEGIN IMMEDIATE")     # a writer holding its transaction open...
        writer._con.execute("INSERT INTO inspections (time, verdict, transform, result_json) "
                            "VALUES ('t', 'pass', '[]', '{}')")
        assert len(reader) == 1                    # ...does not block readers (WAL)
        writer._con.rollback()


def test_control_limits_are_mean_pm_3_sigma_of_the_baseline():
    v = np.array([1.0, 2.0, 3.0, 4.0, 100.0])
    c, lo, hi = control_limits(v, baseline=4)
    s = np.std([1, 2, 3, 4], ddof=1)
    assert (c, lo, hi) == pytest.approx((2.5, 2.5 - 3 * s, 2.5 + 3 * s))
    c, lo, hi = control_limits(v)
    assert c == pytest.approx(v.mean()) and hi - c == pytest.approx(3 * v.std(ddof=1))
    assert np.isnan(control_limits([1.0])[0])
    assert control_limits([1.0, np.nan, 3.0])[0] == pytest.approx(2.0)


def test_plot_trend_writes_a_chart(tmp_path):
    from matplotlib.image import imread

    rng = np.random.default_rng(0)
    with HistoryDB(tmp_path / "h.sqlite") as db:
        for i in range(25):
            mean = 0.01 + rng.normal(0, 0.002) + (0.05 if i == 22 else 0.0)
            verdict = "fail" if i == 22 else ("error" if i == 10 else "pass")
            db.add(FakeResult(verdict=verdict, mean=mean, p95=mean + 0.04, mx=mean + 0.1),
                   part=f"P{i}")
        rows = db.query(limit=None)
    path = plot_trend(rows, tmp_path / "trend.png", baseline=20)
    img = imread(path)
    assert img.shape[0] > 500 and img[..., :3].std() > 0.05
    with pytest.raises(ValueError, match="no inspection records"):
        plot_trend([], tmp_path / "x.png")
    with pytest.raises(ValueError, match="baseline"):
        plot_trend(rows, tmp_path / "x.png", baseline=1)


def test_a_file_that_is_not_a_database_is_rejected(tmp_path):
    path = tmp_path / "notes.sqlite"
    path.write_text("this is not a database, just some text that is long enough " * 20)
    with pytest.raises(ValueError, match="not an SQLite history database"):
        HistoryDB(path)


# ------------------------------------------------ issue 29 item 4: history that shows failures
def _dented(mn=-0.5, region=-0.47, mx=0.08):
    r = FakeResult(verdict="fail", mean=-0.01, p95=0.05, mx=mx)
    r.d["deviation"]["min"] = mn
    r.d["regions"] = [{"kind": "deviation", "n": 40, "area": 30.0, "extreme": region,
                       "extreme_raw": mn, "severity": 2.0, "centroid": [1.0, 2.0, 3.0],
                       "faces": [0], "side": "below"}]
    return r


def test_records_store_signed_min_max_max_abs_region_extremes_and_limits(tmp_path):
    with HistoryDB(tmp_path / "h.sqlite") as db:
        for i in range(5):
            db.add(_dented() if i in (1, 3) else FakeResult(mx=0.08), part=f"P{i}",
                   model_hash="a" * 64)
        rows = db.query()
    bad = [r for r in rows if r["verdict"] == "fail"]
    assert [r["part"] for r in bad] == ["P1", "P3"]
    for r in bad:
        assert (r["min"], r["max"], r["max_abs"]) == (-0.5, 0.08, 0.5)
        assert r["region_min"] == -0.47 and np.isnan(r["region_max"])
        assert (r["lower"], r["upper"]) == (-0.2, 0.2)
        assert r["min"] < r["lower"]          # the chart's top panel marks it beyond the limit
    good = rows[0]
    assert good["max_abs"] == 0.1 and np.isnan(good["region_min"])   # |min| = 0.1 > max 0.08
    plot_trend(rows, tmp_path / "trend.png")


def test_models_are_kept_apart_and_one_chart_shows_one_model(tmp_path):
    cube, hammer = "c0be" + "1" * 60, "c0ff" + "2" * 60
    with HistoryDB(tmp_path / "h.sqlite") as db:
        for i in range(6):
            db.add(FakeResult(), part=f"{'cube' if i % 2 else 'hammer'}{i}",
                   model_hash=cube if i % 2 else hammer)
        assert [m["model_hash"] for m in db.models()] == [hammer, cube]
        assert {r["part"] for r in db.query(model="c0be")} == {"cube1", "cube3", "cube5"}
        assert {r["part"] for r in db.query(model=hammer)} == {"hammer0", "hammer2", "hammer4"}
        with pytest.raises(ValueError, match="start of 2 model hashes"):
            db.query(model="c0")
        with pytest.raises(ValueError, match="no records of model 'beef'"):
            db.query(model="beef")
        rows = db.query()
    with pytest.raises(ValueError, match="2 models.*--model"):
        plot_trend(rows, tmp_path / "mixed.png")
    plot_trend([r for r in rows if r["model_hash"] == cube], tmp_path / "cube.png")


def test_history_command_chooses_a_model(tmp_path):
    from typer.testing import CliRunner

    from shapeverify.cli import app

    model = tmp_path / "cube.stl"
    model.write_bytes(b"solid cube\nendsolid cube\n")
    from shapeverify.pipeline import file_hash

    digest = file_hash(model)
    db_path = tmp_path / "h.sqlite"
    with HistoryDB(db_path) as db:
        db.add(_dented(), part="C1", model_hash=digest)
        db.add(FakeResult(), part="H1", model_hash="f" * 64)
    runner = CliRunner()
    # two models and no --model: the chart is the latest record's model's, and says so
    res = runner.invoke(app, ["history", "--db", str(db_path), "--plot", str(tmp_path / "t.png")],
                        env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    assert "the trend chart shows model ffffffffffff" in res.output and "--model" in res.output
    for key in (str(model), digest[:10]):
        res = runner.invoke(app, ["history", "--db", str(db_path), "--model", key,
                                  "--plot", str(tmp_path / "t.png")], env={"COLUMNS": "200"})
        assert res.exit_code == 0, res.output
        assert "C1" in res.output and "H1" not in res.output
        assert "-0.5000" in res.output and "+0.0800" in res.output     # min and max shown
    assert (tmp_path / "t.png").stat().st_size > 10_000


# the schema of the previous version (2), copied from its code
_V2_SCHEMA = """
CREATE TABLE IF NOT EXISTS inspections (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    part TEXT,
    time TEXT NOT NULL,
    model_hash TEXT,
    verdict TEXT NOT NULL CHECK (verdict IN ('pass', 'fail', 'error', 'incomplete')),
    n INTEGER, mean REAL, std REAL, rms REAL, min REAL, max REAL, p05 REAL, p95 REAL, in_tolerance_fraction REAL,
    n_regions INTEGER,
    transform TEXT NOT NULL,
    result_json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS inspections_part ON inspections (part, id);
"""


@pytest.mark.parametrize("version", [1, 2])
def test_a_database_of_the_previous_schema_opens_and_is_migrated(tmp_path, version):
    path = tmp_path / "old.sqlite"
    schema = _V2_SCHEMA if version == 2 else _V2_SCHEMA.replace(", 'incomplete'", "")
    con = sqlite3.connect(path)
    con.executescript(schema)
    con.execute(f"PRAGMA user_version = {version}")
    for i, res in enumerate([FakeResult(), _dented(), FakeResult(verdict="error", n=0)]):
        d = res.to_dict()
        dev = d["deviation"]
        con.execute("INSERT INTO inspections (part, time, model_hash, verdict, n, mean, std, rms, "
                    "min, max, p05, p95, in_tolerance_fraction, n_regions, transform, result_json) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (f"P{i}", f"2026-01-0{i + 1}T00:00:00", "ab" * 32, d["verdict"], dev["n"],
                     dev["mean"], dev["std"], dev["rms"], dev["min"], dev["max"], dev["p05"],
                     dev["p95"], dev["in_tolerance_fraction"], len(d["regions"]),
                     json.dumps(d["T_model_scan"]), json.dumps(d)))
    con.commit()
    con.close()
    with HistoryDB(path) as db:
        rows = db.query()
        assert [r["part"] for r in rows] == ["P0", "P1", "P2"]
        assert rows[1]["max_abs"] == 0.5 and rows[1]["region_min"] == -0.47
        assert rows[0]["max_abs"] == 0.1 and rows[0]["upper"] == 0.2
        assert db.get(rows[1]["id"])["result"]["regions"][0]["extreme"] == -0.47
        rid = db.add(FakeResult(verdict="incomplete"), part="P3", model_hash="ab" * 32)
        assert db.query(model="abab")[-1]["id"] == rid
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA user_version").fetchone()[0] == 3
    con.close()
    with HistoryDB(path) as db:                   # opening again changes nothing
        assert len(db) == 4


def test_two_processes_opening_an_old_database_at_once_migrate_it_once(tmp_path):
    """Service workers open the history together: the check and the migration are one write
    transaction (without it the second ALTER TABLE failed: duplicate column)."""
    from concurrent.futures import ThreadPoolExecutor

    path = tmp_path / "old.sqlite"
    con = sqlite3.connect(path)
    con.executescript(_V2_SCHEMA)
    con.execute("PRAGMA user_version = 2")
    d = _dented().to_dict()
    con.execute("INSERT INTO inspections (time, verdict, transform, result_json) VALUES "
                "('t', 'fail', '[]', ?)", (json.dumps(d),))
    con.commit()
    con.close()

    def open_and_count(_):
        with HistoryDB(path) as db:
            return db.query()[0]["max_abs"]

    with ThreadPoolExecutor(4) as pool:
        assert list(pool.map(open_and_count, range(8))) == [0.5] * 8
