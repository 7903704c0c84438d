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
