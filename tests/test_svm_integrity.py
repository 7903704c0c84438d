"""Issue 33 row 5: crafted or damaged ``.svm`` files are a clear error, never a crash or a hang.

Before: a tree child index out of range made ``load_prepared`` + a query die with SIGSEGV
(exit 139); a cycle in the tree made a query loop for ever.  Now the file's header holds the
SHA-256 of its arrays and loading checks the sizes, the index ranges and that the tree is a tree
(:mod:`shapeverify.nearest._svm_checks`) -- also for files written before the checksum existed.

The fuzz mutates a prepared model's file with hypothesis (bytes flipped, the file or one array
truncated, one index or value changed, in three header modes: the stale checksum kept, the
checksum removed -- an old file --, or recomputed -- a forger) and loads each mutant in a child
process (``_svm_fuzz_worker.py``) with a time bound, so a crash or a hang is a test failure and
not a dead pytest.  What may happen: a ``ModelFileError`` naming the file, or a model that
answers the fast and exact queries exactly as the original; without a valid checksum (an old or
forged file) also a model that answers differently -- but never a crash, a hang, or another
exception.
"""

from __future__ import annotations

import collections
import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import shapeverify as sv
from shapeverify.errors import ModelFileError
from shapeverify.nearest import load_prepared
from shapeverify.nearest import _svm_checks

WORKER = Path(__file__).with_name("_svm_fuzz_worker.py")
SRC = Path(__file__).resolve().parents[1] / "src"
TIME_BOUND_S = 60.0  # per mutant (a load and two queries take ~0.05 s)


# ---------------------------------------------------------------------------------- helpers
def _arrays(path) -> tuple[dict, dict]:
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in z.files}
    return json.loads(bytes(a.pop("meta")).decode()), a


def _write(path, meta: dict, arrays: dict, checksum: str) -> Path:
    """Write ``arrays`` with ``meta``; ``checksum``: "keep" (as in meta), "drop" (an old file),
    "fix" (recomputed: the file is consistent with its header)."""
    meta = dict(meta)
    if checksum == "drop":
        meta.pop("sha256", None)
    elif checksum == "fix":
        meta["sha256"] = _svm_checks.payload_digest(arrays)
    out = dict(arrays)
    out["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    with open(path, "wb") as fh:
        np.savez(fh, **out)
    return Path(path)


def _cyclic(nodes: np.ndarray, dims) -> np.ndarray:
    """Every entry of every child block pointed at its own block: a descent into any
    internal top-grid cell then loops for ever (each block its own only child)."""
    n_top = int(np.prod(dims))
    out = nodes.copy()
    j = np.arange(n_top, nodes.size)
    out[j] = n_top + 8 * ((j - n_top) // 8)
    return out


def _inner_entries(nodes: np.ndarray, dims) -> np.ndarray:
    """Positions in ``nodes`` of internal cells (code >= 0) that lie inside a child block."""
    n_top = int(np.prod(dims))
    pos = np.flatnonzero(nodes >= 0)
    return pos[pos >= n_top]


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """A prepared CAD model (the bundled chamfered plate: 10 faces, a tree of depth >= 2)."""
    from shapeverify.cad.examples import chamfered_plate_step

    d = tmp_path_factory.mktemp("svm")
    model = sv.load_model(chamfered_plate_step(d / "plate.step"))
    prep = sv.prepare(model, spacing=2.0)
    path = d / "plate.svm"
    prep.save(path)
    rng = np.random.default_rng(5)
    pts = prep.points.points[rng.choice(prep.n_points, 150, replace=False)]
    nrm = prep.points.normals[rng.choice(prep.n_points, 150, replace=False)]
    q = np.concatenate([pts + rng.normal(0, 1.0, pts.shape) + 0.5 * nrm,
                        pts[:20] + 3 * prep.reach])  # the last beyond the reach: the kd-tree
    np.save(d / "queries.npy", q)
    return path, d / "queries.npy"


class Worker:
    """One ``_svm_fuzz_worker.py`` child; restarted after a crash or a hang."""

    def __init__(self, original, queries):
        self.args = [sys.executable, str(WORKER), str(original), str(queries)]
        self.proc = None

    def start(self):
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get(
            "PYTHONPATH", "")]))
        self.proc = subprocess.Popen(self.args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, env=env, text=True, bufsize=1)
        assert self._line(300.0) == "ready"

    def _line(self, wait):
        ready, _, _ = select.select([self.proc.stdout], [], [], wait)
        if not ready:
            return None
        return self.proc.stdout.readline().strip()

    def load(self, path) -> str:
        if self.proc is None or self.proc.poll() is not None:
            self.start()
        self.proc.stdin.write(f"{path}\n")
        self.proc.stdin.flush()
        line = self._line(TIME_BOUND_S)
        if line is None:
            self.stop()
            return "HANG"
        if line == "":
            rc = self.proc.wait()
            self.proc = None
            return f"CRASH {rc}"
        return line

    def stop(self):
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None


@pytest.fixture(scope="module")
def worker(original):
    w = Worker(*original)
    yield w
    w.stop()


# ------------------------------------------------------------------- the rows of the issue
@pytest.mark.parametrize("checksum", ["keep", "drop", "fix"])
def test_row5_tree_child_index_out_of_range_is_an_error_not_sigsegv(original, worker,
                                                                    tmp_path, checksum):
    meta, a = _arrays(original[0])
    nodes = a["tree_nodes"].copy()
    top = np.flatnonzero(nodes[:int(np.prod(a["tree_dims"]))] >= 0)
    nodes[top[0]] = nodes.size + 1000  # a child block far past the end
    a["tree_nodes"] = nodes
    path = _write(tmp_path / "child-out-of-range.svm", meta, a, checksum)
    with pytest.raises(ModelFileError) as err:
        load_prepared(path)
    msg = str(err.value)
    assert "child-out-of-range.svm" in msg and "shapeverify prepare" in msg
    assert ("checksum" in msg) if checksum == "keep" else ("child index is out of range" in msg)
    assert worker.load(path) == "error ModelFileError"


@pytest.mark.parametrize("checksum", ["keep", "drop", "fix"])
def test_row5_tree_cycle_is_an_error_not_a_hang(original, worker, tmp_path, checksum):
    meta, a = _arrays(original[0])
    assert _inner_entries(a["tree_nodes"], a["tree_dims"]).size, "needs a tree of depth >= 2"
    a["tree_nodes"] = _cyclic(a["tree_nodes"], a["tree_dims"])
    path = _write(tmp_path / "cycle.svm", meta, a, checksum)
    t0 = time.perf_counter()
    with pytest.raises(ModelFileError) as err:
        load_prepared(path)
    assert "cycle.svm" in str(err.value)
    if checksum != "keep":
        assert "not a tree" in str(err.value)
    assert time.perf_counter() - t0 < 10.0
    assert worker.load(path) == "error ModelFileError"


@pytest.mark.slow
def test_row5_the_checks_are_what_prevents_the_crash_and_the_hang(original, tmp_path):
    """Without check_structure the same files crash or hang the process (the bug itself):
    each runs in a child process with a 20 s bound."""
    meta, a = _arrays(original[0])
    n_top = int(np.prod(a["tree_dims"]))
    nodes = a["tree_nodes"]
    cases = {}
    bad = nodes.copy()
    bad[np.flatnonzero(nodes[:n_top] >= 0)] = 2**31 - 100
    cases["oob"] = _write(tmp_path / "oob.svm", meta, dict(a, tree_nodes=bad), "drop")
    bad = _cyclic(nodes, a["tree_dims"])
    cases["cycle"] = _write(tmp_path / "cyc.svm", meta, dict(a, tree_nodes=bad), "drop")
    code = ("import sys, numpy as np\n"
            "from shapeverify.nearest import _svm_checks, prepared\n"
            "prepared.check_structure = lambda *a: None\n"
            "p = prepared.load_prepared(sys.argv[1])\n"
            "q = np.load(sys.argv[2])\n"
            "p.closest(q)\nprint('answered')\n")
    env = dict(os.environ, PYTHONPATH=str(SRC))
    outcome = {}
    for name, path in cases.items():
        try:
            r = subprocess.run([sys.executable, "-c", code, str(path), str(original[1])],
                               capture_output=True, timeout=20, env=env)
            outcome[name] = r.returncode
        except subprocess.TimeoutExpired:
            outcome[name] = "hang"
    assert outcome["cycle"] == "hang", outcome
    assert outcome["oob"] != 0, outcome  # SIGSEGV (-11) or another abnormal end


def test_row5_checksum_is_written_and_checked(original, tmp_path):
    meta, a = _arrays(original[0])
    assert meta["sha256"] == _svm_checks.payload_digest(a)
    # a change that keeps every index in range is caught by the checksum alone
    rec = a["rec"].copy()
    rec[0, 0] += 1e-9
    path = _write(tmp_path / "moved.svm", meta, dict(a, rec=rec), "keep")
    with pytest.raises(ModelFileError, match="moved.svm.*checksum"):
        load_prepared(path)


def test_row5_old_file_without_checksum_still_loads(original, tmp_path):
    meta, a = _arrays(original[0])
    path = _write(tmp_path / "old.svm", meta, a, "drop")
    old, new = load_prepared(path), load_prepared(original[0])
    q = np.load(original[1])
    np.testing.assert_array_equal(old.closest(q).distances, new.closest(q).distances)


def test_row5_array_sizes_against_header(original, tmp_path):
    meta, a = _arrays(original[0])
    for name, bad in (("rows", a["rows"][:-1]), ("rec", a["rec"][:-3]),
                      ("tree_lists", a["tree_lists"][:0]), ("boundary", a["boundary"][1:])):
        path = _write(tmp_path / f"short-{name}.svm", meta, dict(a, **{name: bad}), "fix")
        with pytest.raises(ModelFileError, match=f"short-{name}.svm"):
            load_prepared(path)
    path = _write(tmp_path / "header.svm", dict(meta, n_points=meta["n_points"] + 1), a, "fix")
    with pytest.raises(ModelFileError, match="header.svm"):
        load_prepared(path)


# ------------------------------------------------------------------------------- the fuzz
_INDEX_ARRAYS = ("tree_nodes", "tree_lists", "rows", "rec", "tree_dims", "model_loop_len",
                 "model_face_nloops", "model_shapes", "model_knots_u_len")


@st.composite
def mutations(draw):
    kind = draw(st.sampled_from(["flip", "truncate_file", "index", "truncate_array", "value"]))
    return {"kind": kind, "checksum": draw(st.sampled_from(["keep", "drop", "fix"])),
            "name": draw(st.sampled_from(_INDEX_ARRAYS)),
            "seed": draw(st.integers(0, 2**32 - 1)),
            "value": draw(st.sampled_from([-2**31, -3, -2, -1, 0, 1, 7, 8, 2**31 - 1, 10**6]))}


def _mutant(original: Path, m: dict, path: Path) -> Path:
    rng = np.random.default_rng(m["seed"])
    raw = original.read_bytes()
    if m["kind"] == "flip":
        b = bytearray(raw)
        for p in rng.integers(0, len(b), size=int(rng.integers(1, 6))):
            b[p] ^= int(rng.integers(1, 256))
        path.write_bytes(bytes(b))
        return path
    if m["kind"] == "truncate_file":
        path.write_bytes(raw[:int(rng.integers(0, len(raw)))])
        return path
    meta, a = _arrays(original)
    arr = a[m["name"]].copy()
    flat = arr.reshape(-1)
    if m["kind"] == "truncate_array":
        arr = arr[:int(rng.integers(0, max(1, arr.shape[0])))] if arr.ndim else arr
    elif flat.size and m["kind"] == "index":  # an entry set to a boundary value
        if m["name"] == "rec":  # a neighbour index of a record
            iv = arr.view(np.int32)
            iv[int(rng.integers(0, iv.shape[0])), 6 + int(rng.integers(0, 8))] = m["value"]
        else:
            flat[int(rng.integers(0, flat.size))] = np.asarray(m["value"]).astype(arr.dtype)
    elif flat.size:  # an entry set to another entry's value (plausible, in range)
        flat[int(rng.integers(0, flat.size))] = flat[int(rng.integers(0, flat.size))]
    a[m["name"]] = arr
    return _write(path, meta, a, m["checksum"])


def _check_outcome(out: str, m: dict, tally: collections.Counter):
    key = f"{m['kind']}/{m['checksum']}: {out.split(' ')[0]}"
    tally[key] += 1
    assert not out.startswith(("HANG", "CRASH", "other", "unnamed")), (m, out)
    if m["kind"] in ("flip", "truncate_file") or m["checksum"] == "keep":
        assert out in ("same", "error ModelFileError"), (m, out)


def _run_fuzz(original, worker, tmp_path_factory, n):
    tally = collections.Counter()
    d = tmp_path_factory.mktemp("mutants")
    count = [0]
    t0 = time.perf_counter()

    @settings(max_examples=n, deadline=None, database=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(mutations())
    def one(m):
        count[0] += 1
        path = _mutant(original[0], m, d / f"m{count[0]}.svm")
        _check_outcome(worker.load(path), m, tally)
        path.unlink()

    one()
    wall = time.perf_counter() - t0
    print(f"\n.svm fuzz: {count[0]} mutants in {wall:.1f} s")
    for k, v in sorted(tally.items()):
        print(f"  {k}: {v}")
    return tally


def test_row5_fuzz_svm_mutants_never_crash_or_hang(original, worker, tmp_path_factory):
    tally = _run_fuzz(original, worker, tmp_path_factory, 60)
    assert sum(tally.values()) >= 60


@pytest.mark.slow
def test_row5_fuzz_svm_many_mutants(original, worker, tmp_path_factory):
    tally = _run_fuzz(original, worker, tmp_path_factory, 1000)
    assert sum(tally.values()) >= 1000
