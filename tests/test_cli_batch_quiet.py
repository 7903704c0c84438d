"""``shapeverify batch`` shows a progress bar and the summary, not Dask's log (issue 32, item 6:
35 INFO lines of the scheduler, nannies and clients flooded the terminal).  Dask's lines go to
``OUT/dask.log``; with ``shapeverify --verbose`` they reach the terminal too."""

from __future__ import annotations

import logging
import os
import subprocess
import sys

import pytest

pytest.importorskip("distributed")


def test_dask_records_go_to_the_file_and_to_the_terminal_only_when_verbose(tmp_path):
    from shapeverify.batch import _dask_logs_to

    seen = []

    class Collect(logging.Handler):
        def emit(self, record):
            seen.append(record.getMessage())

    root = logging.getLogger()
    old_level = root.level
    handler = Collect()
    root.addHandler(handler)
    dlog = logging.getLogger("distributed.scheduler")
    old_dlevel = dlog.level
    dlog.setLevel(logging.INFO)
    try:
        for level, name in ((logging.WARNING, "quiet.log"), (logging.INFO, "verbose.log")):
            root.setLevel(level)
            with _dask_logs_to(tmp_path / name):
                dlog.info("Scheduler at: tcp://127.0.0.1:1 (%s)", name)
            assert "Scheduler at" in (tmp_path / name).read_text()
        assert seen == ["Scheduler at: tcp://127.0.0.1:1 (verbose.log)"]
        assert logging.getLogger("distributed").propagate      # restored after the run
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)
        dlog.setLevel(old_dlevel)


@pytest.mark.slow
def test_batch_terminal_shows_the_summary_not_dasks_info_lines(tmp_path):
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare
    from shapeverify.simulate import virtual_scan

    model = load_model(example_part_step(tmp_path / "panel.step"))
    prepare(model, spacing=3.0).save(tmp_path / "panel.svm")
    scans = tmp_path / "scans"
    scans.mkdir()
    import numpy as np

    np.save(scans / "a.npy", virtual_scan(model, pixel=5.0, noise=0.02, rng=1).scan)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "shapeverify", "batch", str(tmp_path / "panel.svm"),
                           str(scans), "--out", str(out), "--tolerance", "0.3", "--workers", "1"],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "COLUMNS": "200"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "1 scans (0 already done): 1 pass" in proc.stdout
    terminal = proc.stdout + proc.stderr
    assert "INFO" not in terminal and "Nanny" not in terminal and "Scheduler" not in terminal, terminal
    log = (out / "dask.log").read_text()
    assert "Nanny" in log and "INFO" in log
    assert "Dask's log:" in proc.stdout and "dask.log" in proc.stdout
