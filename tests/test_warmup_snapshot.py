"""``python -m shapeverify.warmup --snapshot DIR`` (``make``'s set-up) keeps a copy of what the
warm-up wrote to an empty numba cache, which tests/test_warmup_coverage.py runs its commands on
instead of compiling everything again (216 s of the fresh clone's suite).  The copy must be
exactly the warm-up's files, laid out so numba loads them from a ``NUMBA_CACHE_DIR`` without
compiling, and there must be none when the cache held entries before the warm-up (they would
not be the warm-up's alone).  Here the warm-up is one small kernel of the package, compiled in
a process of its own on an empty ``NUMBA_CACHE_DIR``."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

from test_warmup_coverage import _usable_snapshot

# the warm-up replaced by one kernel of the package (sort_rows), then main as make runs it
WARM = r"""
import sys
import numpy as np
import shapeverify.warmup as w


def one_kernel(say):
    from shapeverify.nearest._seedlist_kernels import sort_rows
    sort_rows(np.array([[3, 1], [2, 5]], np.int32), np.array([2, 1], np.int32))
    return 0.0


w.warm_up = one_kernel
sys.exit(w.main(["--quiet", "--snapshot", sys.argv[1]]))
"""

# the kernel again, with the number of compilations numba reports
LOAD = r"""
import numpy as np
from numba.core import event

n = []


class _L(event.Listener):
    def on_start(self, ev):
        n.append(1)

    def on_end(self, ev):
        pass


event.register("numba:compile", _L())
from shapeverify.nearest._seedlist_kernels import sort_rows
sort_rows(np.array([[4, 0], [1, 1]], np.int32), np.array([2, 2], np.int32))
print(len(n))
"""


def _run(script: str, cache: Path, *args) -> subprocess.CompletedProcess:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    proc = subprocess.run([sys.executable, "-c", script, *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def test_snapshot_is_the_warm_ups_cache_files_and_loads_without_compiling(tmp_path):
    from shapeverify.warmup import sources_stamp

    cache, snap = tmp_path / "cache", tmp_path / "snap"
    _run(WARM, cache, snap)
    made = {str(p.relative_to(cache)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in cache.rglob("*") if p.is_file()}
    assert any(k.endswith(".nbc") for k in made) and any(k.endswith(".nbi") for k in made)
    manifest = json.loads((snap / "manifest.json").read_text())
    assert manifest["files"] == made                     # the same names, the same bytes
    assert manifest["stamp"] == sources_stamp()
    assert _usable_snapshot(snap, sources_stamp()) == manifest
    # numba finds the kernel in the copy, laid out as a NUMBA_CACHE_DIR: no compilation
    assert _run(LOAD, snap / "numba").stdout.split() == ["0"]
    assert int(_run(LOAD, tmp_path / "empty").stdout) > 0     # the count is live


def test_no_snapshot_when_the_cache_held_entries_before_the_warm_up(tmp_path):
    cache, snap = tmp_path / "cache", tmp_path / "snap"
    _run(WARM, cache, snap)
    assert (snap / "manifest.json").is_file()
    _run(WARM, cache, snap)                              # the cache has the kernel already
    assert not snap.exists()


def test_a_snapshot_of_other_sources_or_changed_files_is_not_used(tmp_path):
    from shapeverify.warmup import sources_stamp

    cache, snap = tmp_path / "cache", tmp_path / "snap"
    _run(WARM, cache, snap)
    stamp = sources_stamp()
    assert _usable_snapshot(snap, stamp) is not None
    assert _usable_snapshot(snap, "0" * 64) is None                  # other sources
    nbc = next((snap / "numba").rglob("*.nbc"))
    nbc.write_bytes(nbc.read_bytes() + b"\0")                        # a changed copy
    assert _usable_snapshot(snap, stamp) is None
