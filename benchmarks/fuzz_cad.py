"""Large CAD fuzz run (issue 33, "How good"): N mutated STEP/IGES files through ``info`` and
``prepare``, with a time and memory bound per mutant and an oracle for silently wrong content.

Each mutant is one seeded damage of a small undamaged file (the bundled example panel as STEP
and IGES, the turned part, the chamfered plate, and ``../shared/data/cad/wavy-cube.stp`` when
present): an entity line removed, a line duplicated, bytes flipped, the file truncated, a
reference left dangling, a shell's face removed, two tokens swapped, a number replaced by another
finite number, or by one outside the float range (``NaN``, ``1.E+400``, ``9.99D+99``, ``-INF``,
``*``, ``1.0D+999``).  The mutants are made here (in the parent, which never imports
OpenCASCADE) and sent to a persistent *worker* process (``nice -n 10``, its address space limited
to ``--mem-gb`` with ``resource.setrlimit``, which the importer child it starts inherits), which
runs

* ``info``: :func:`shapeverify.cad.summary.read_summary` (the importer child, OpenCASCADE alone);
* ``prepare``: :func:`shapeverify.load_model` (the importer child) and
  :func:`shapeverify.prepare` at spacing ``size / 20``.

Outcomes per stage: ``ok``, ``ok (faces missing, warned)``, an input error (its class),
``importer crashed`` (contained: a signal in the importer child), ``importer timeout`` (the
importer killed by a watchdog after ``--hang-s`` seconds of *CPU* on one import: a *hang*;
the wall clock is only a backstop at 10 x that, since a nice'd process on a loaded machine can
wait minutes for a core), ``memory`` (MemoryError: the limit was hit), or
``BUG <exception>`` (an exception that is not an input error).  The parent restarts the worker
when it dies (a *parent crash*: the process that ran ``info``/``prepare`` died) or does not
spends over ``2 * hang-s`` of its own CPU on one mutant (a *parent hang*).

Silently wrong (each counted, and the first ones listed in the results):

* a mutant with a number outside the float range that is accepted by ``info`` or ``load_model``;
* ``info`` or ``load_model`` giving fewer faces than the file declares without naming the missing
  ones (``faces_in_file`` / ``n_missing_faces``), or fewer faces than the undamaged file when the
  mutant declares as many faces as the undamaged one;
* a model with faces missing that ``prepare`` accepts (it must raise ``IncompleteModelError``);
* non-finite bounds.

Run (about 0.1-0.3 s of one core per mutant; the results go to ``benchmarks/results_fuzz.md``)::

    PYTHONPATH=src .venv/bin/python benchmarks/fuzz_cad.py -n 10000 --budget-s 3600
    PYTHONPATH=src .venv/bin/python benchmarks/fuzz_cad.py -n 50 --out /tmp/fuzz.md   # smoke

``tests/test_fuzz_cad.py`` runs a few dozen of these mutants through the same worker.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED_CAD = ROOT.parent / "shared" / "data" / "cad"
SEED = 20261206
#: the wall-clock backstop of an import, in multiples of the CPU limit of a hang
WALL_FACTOR = 10.0
EXTREME = {"step": [b"NaN", b"1.E+400", b"-INF", b"*", b"9.99D+99"],
           "iges": [b"NaN", b"1.E+400", b"-INF", b"1.0D+999"]}


# ------------------------------------------------------------------------------ the damage
def _entity_lines(lines, fmt):
    if fmt == "step":
        return [i for i, ln in enumerate(lines) if ln.startswith(b"#")]
    return [i for i, ln in enumerate(lines) if len(ln) > 72 and ln[72:73] in (b"D", b"P")]


def remove_entity_line(data, fmt, rng):
    lines = data.splitlines(keepends=True)
    del lines[int(rng.choice(_entity_lines(lines, fmt)))]
    return b"".join(lines)


def duplicate_line(data, fmt, rng):
    lines = data.splitlines(keepends=True)
    i = int(rng.choice(_entity_lines(lines, fmt)))
    return b"".join(lines[:i + 1] + [lines[i]] + lines[i + 1:])


def flip_bytes(data, fmt, rng):
    b = bytearray(data)
    for pos in rng.integers(0, len(b), size=int(rng.integers(1, 9))):
        b[pos] ^= int(rng.integers(1, 256))
    return bytes(b)


def truncate(data, fmt, rng):
    return data[:int(rng.integers(len(data) // 10, len(data) - 1))]


def dangling_reference(data, fmt, rng):
    lines = data.splitlines(keepends=True)
    if fmt == "step":
        cand = [i for i, ln in enumerate(lines) if ln.startswith(b"#") and ln.count(b"#") > 1]
        i = int(rng.choice(cand))
        refs = list(re.finditer(rb"#\d+", lines[i]))[1:]
        m = refs[int(rng.integers(len(refs)))]
        lines[i] = lines[i][:m.start()] + b"#987654" + lines[i][m.end():]
    else:
        cand = [i for i, ln in enumerate(lines) if len(ln) > 72 and ln[72:73] == b"P"
                and re.search(rb"[,;]\d*[13579][,;]", ln[:64])]
        i = int(rng.choice(cand))
        ms = list(re.finditer(rb"(?<=[,;])\d*[13579](?=[,;])", lines[i][:64]))
        m = ms[int(rng.integers(len(ms)))]
        lines[i] = lines[i][:m.start()] + b"9" * (m.end() - m.start()) + lines[i][m.end():]
    return b"".join(lines)


def dangling_face(data, fmt, rng):
    lines = data.splitlines(keepends=True)
    if fmt == "step":
        text = b"".join(lines)
        shell = re.search(rb"(?:CLOSED|OPEN)_SHELL\('[^']*',\(([^)]*)\)", text)
        refs = re.findall(rb"#(\d+)", shell.group(1))
        face = refs[int(rng.integers(len(refs)))]
        return b"".join(ln for ln in lines if not ln.startswith(b"#" + face + b" ="))
    de = [i for i, ln in enumerate(lines) if ln[72:73] == b"D" and ln[:8].strip() in (b"144", b"510")
          and int(ln[73:80]) % 2 == 1]
    i = int(rng.choice(de))
    return b"".join(lines[:i] + lines[i + 2:])


_STEP_NUM = rb"(?<=[(,])-?\d+\.\d*(?:E[+-]?\d+)?(?=[,)])"
_IGES_NUM = rb"(?<=[,;])-?\d*\.\d*(?:[ED][+-]?\d+)?(?=[,;])"


def _numbers(data, fmt):
    """(start, end) of the real numbers of the data section."""
    if fmt == "step":
        start = data.find(b"DATA;")
        return [(m.start(), m.end()) for m in re.finditer(_STEP_NUM, data) if m.start() > start]
    out, pos = [], 0
    for ln in data.splitlines(keepends=True):
        if ln[72:73] == b"P":
            out += [(pos + m.start(), pos + m.end()) for m in re.finditer(_IGES_NUM, ln[:64])]
        pos += len(ln)
    return out


def _put(data, fmt, span, tok):
    a, b = span
    if fmt == "iges":  # fixed columns: keep the line's length (a longer token is cut short)
        tok = tok.rjust(b - a) if len(tok) <= b - a else tok[:b - a]
    return data[:a] + tok + data[b:]


def extreme_number(data, fmt, rng):
    """A real number replaced by one outside the float range (issue 33 row 4)."""
    toks = EXTREME[fmt]
    tok = toks[int(rng.integers(len(toks)))]
    spans = _numbers(data, fmt)
    if fmt == "step" and tok == b"*":  # '*' only inside a list of coordinates
        spans = [s for s in spans if re.match(rb",-?\d", data[s[1]:s[1] + 3])]
    if fmt == "iges":
        spans = [s for s in spans if s[1] - s[0] >= len(tok)]
    return _put(data, fmt, spans[int(rng.integers(len(spans)))], tok)


def finite_number(data, fmt, rng):
    """A real number replaced by another finite one (huge, tiny, zero, negated, shifted)."""
    spans = _numbers(data, fmt)
    a, b = spans[int(rng.integers(len(spans)))]
    try:
        v = float(data[a:b].replace(b"D", b"E"))
    except ValueError:
        v = 1.0
    choice = int(rng.integers(6))
    new = [1e300, 1e-300, 0.0, -v, v + float(rng.normal(0, 10)), 1e15][choice]
    text = repr(float(new)).upper().encode()
    if fmt == "step" and b"." not in text:
        text = text.replace(b"E", b".E") if b"E" in text else text + b"."
    return _put(data, fmt, (a, b), text)


def swap_tokens(data, fmt, rng):
    """Two tokens (numbers, references or keywords) of the data section swapped."""
    pat = rb"#\d+|[A-Z_]{3,}|-?\d+\.\d*(?:[ED][+-]?\d+)?" if fmt == "step" else rb"-?\d+\.?\d*(?:[ED][+-]?\d+)?"
    start = data.find(b"DATA;") if fmt == "step" else 0
    ms = [m for m in re.finditer(pat, data) if m.start() > start]
    if fmt == "iges":
        pos, keep = 0, set()
        for ln in data.splitlines(keepends=True):
            if ln[72:73] == b"P":
                keep.add(pos)
            pos += len(ln)
        starts = sorted(keep)
        import bisect
        ms = [m for m in ms if (k := bisect.bisect_right(starts, m.start()) - 1) >= 0
              and m.start() - starts[k] < 64 and m.end() - starts[k] <= 64]
    i, j = sorted(rng.choice(len(ms), size=2, replace=False))
    x, y = ms[int(i)], ms[int(j)]
    tx, ty = data[x.start():x.end()], data[y.start():y.end()]
    if fmt == "iges":  # keep the columns
        w1, w2 = len(tx), len(ty)
        tx, ty = ty[:w1].rjust(w1), tx[:w2].rjust(w2)
        return data[:x.start()] + tx + data[x.end():y.start()] + ty + data[y.end():]
    return data[:x.start()] + ty + data[x.end():y.start()] + tx + data[y.end():]


DAMAGE = [remove_entity_line, duplicate_line, flip_bytes, truncate, dangling_reference,
          dangling_face, extreme_number, finite_number, swap_tokens]


# ------------------------------------------------------------------------------ the sources
def make_sources(folder: Path, shared: bool = True) -> dict[str, Path]:
    """The undamaged files: small real parts (the worker imports OpenCASCADE, not this process)."""
    script = r"""
import sys
from pathlib import Path
from OCP.IGESControl import IGESControl_Writer
from shapeverify.cad.examples import (chamfered_plate_step, example_part_step, panel_shape,
                                      turned_part_step)
d = Path(sys.argv[1])
example_part_step(d / "panel.step")
turned_part_step(d / "turned.step", keyway=True)
chamfered_plate_step(d / "plate.step")
w = IGESControl_Writer("MM", 0)
w.AddShape(panel_shape())
w.ComputeModel()
assert w.Write(str(d / "panel.igs"))
"""
    folder.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, "-c", script, str(folder)], check=True)
    files = {p.name: p for p in sorted(folder.iterdir())}
    if shared and (SHARED_CAD / "wavy-cube.stp").is_file():
        files["wavy-cube.stp"] = SHARED_CAD / "wavy-cube.stp"
    return files


def fmt_of(path) -> str:
    return "step" if Path(path).suffix.lower() in (".step", ".stp") else "iges"


# ------------------------------------------------------------------------------ the worker
def _worker_main(hang_s: float) -> None:
    """Read one JSON request per line on stdin, answer one JSON line on stdout."""
    import logging

    import shapeverify as sv
    from shapeverify.cad import occ_worker
    from shapeverify.cad.face_count import declared_faces
    from shapeverify.cad.summary import read_summary
    from shapeverify.errors import IncompleteModelError, ShapeVerifyError, is_input_error

    # a hang is counted in CPU seconds (a watchdog kills an importer that spends more than
    # hang_s of CPU on one request); the wall-clock limit is only a backstop, because on a
    # loaded machine a nice'd importer can wait minutes for a core
    occ_worker.DEFAULT_TIMEOUT_S = max(WALL_FACTOR * hang_s, 600.0)
    import threading

    watch = {"pid": None, "cpu0": 0.0, "killed": False, "on": False}

    def proc_cpu(pid):
        try:
            f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            return None

    def watchdog():
        while True:
            time.sleep(0.5)
            if not watch["on"]:
                continue
            imp = occ_worker._CURRENT
            if imp is None or imp.proc.poll() is not None:
                continue
            pid = imp.proc.pid
            c = proc_cpu(pid)
            if c is None:
                continue
            if watch["pid"] != pid:          # a new importer during this request: from its start
                watch["pid"], watch["cpu0"] = pid, 0.0
            if c - watch["cpu0"] > hang_s:
                watch["killed"] = True
                try:
                    os.kill(pid, 9)
                except OSError:
                    pass

    threading.Thread(target=watchdog, daemon=True).start()

    def watch_start():
        imp = occ_worker._CURRENT
        pid = imp.proc.pid if imp is not None and imp.proc.poll() is None else None
        watch["pid"], watch["cpu0"] = pid, (proc_cpu(pid) or 0.0) if pid else 0.0
        watch["killed"], watch["on"] = False, True
    logging.getLogger("shapeverify").setLevel(logging.WARNING)
    warnings: list[str] = []

    class _H(logging.Handler):
        def emit(self, record):
            warnings.append(record.getMessage())

    logging.getLogger("shapeverify").addHandler(_H(logging.WARNING))
    logging.getLogger("shapeverify").propagate = False
    out = sys.stdout
    warm = sys.stdin.readline().strip()  # a clean file: import, prepare (numba compiles), then say so
    if warm:
        try:
            sv.prepare(sv.load_model(warm), spacing=None)
            read_summary(warm)
        except Exception as exc:  # noqa: BLE001
            out.write(json.dumps({"ready": f"warm-up failed: {exc}"}) + "\n")
        else:
            out.write(json.dumps({"ready": "ok"}) + "\n")
        out.flush()

    def importer_hwm() -> int:
        imp = occ_worker._CURRENT
        if imp is None or imp.proc.poll() is not None:
            return 0
        try:
            for ln in Path(f"/proc/{imp.proc.pid}/status").read_text().splitlines():
                if ln.startswith("VmHWM:"):
                    return int(ln.split()[1]) // 1024
        except OSError:
            pass
        return 0

    def classify(exc) -> str:
        msg = str(exc)
        if isinstance(exc, MemoryError):
            return "memory"
        if "did not finish within" in msg:
            return "importer timeout (wall)"
        if "importer crashed" in msg and watch["killed"]:
            return f"importer hang (over {hang_s:g} s of CPU)"
        if "importer crashed" in msg:
            return "importer crashed" + (" (memory?)" if "SIGABRT" in msg or "signal 6" in msg else "")
        if isinstance(exc, ShapeVerifyError) and is_input_error(exc):
            return type(exc).__name__
        if isinstance(exc, (OSError, ValueError)) and is_input_error(exc):
            return type(exc).__name__
        return f"BUG {type(exc).__name__}: {msg[:200]}"

    import resource

    def importer_cpu():
        """(pid, CPU s) of the live importer, or (None, 0)."""
        imp = occ_worker._CURRENT
        if imp is None or imp.proc.poll() is not None:
            return None, 0.0
        try:
            f = Path(f"/proc/{imp.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
            return imp.proc.pid, (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            return None, 0.0

    def cpu_now():
        me = resource.getrusage(resource.RUSAGE_SELF)
        ch = resource.getrusage(resource.RUSAGE_CHILDREN)
        return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime, importer_cpu()

    for line in sys.stdin:
        req = json.loads(line)
        c0, (pid0, ic0) = cpu_now()
        path, orig, damage = Path(req["path"]), int(req["orig_faces"]), req["damage"]
        fmt = fmt_of(path)
        res = {"wrong": []}
        try:
            declared = declared_faces(path, fmt)[0]
        except Exception:  # noqa: BLE001
            declared = -1
        # info
        warnings.clear()
        t0 = time.perf_counter()
        watch_start()
        try:
            s = read_summary(path)
            miss = (s.faces_in_file or s.faces) - s.faces
            res["info"] = "ok (faces missing, named)" if (miss and s.missing) else "ok"
            if damage == "extreme_number":
                res["wrong"].append("info accepted a number outside the float range")
            if miss > 0 and not s.missing:
                res["wrong"].append(f"info: {miss} faces missing, not named")
            if s.faces < orig and not miss and declared >= orig:
                res["wrong"].append(f"info: {s.faces} faces of {orig}, file declares {declared}, no warning")
            if not np.isfinite(np.asarray(s.lo + s.hi, float)).all():
                res["wrong"].append("info: non-finite bounds")
        except BaseException as exc:  # noqa: BLE001
            if isinstance(exc, KeyboardInterrupt):
                raise
            res["info"] = classify(exc)
        res["t_info"] = time.perf_counter() - t0
        # prepare
        warnings.clear()
        t0 = time.perf_counter()
        watch_start()
        try:
            model = sv.load_model(path)
            miss = model.n_missing_faces
            nf = len(model.faces)
            if damage == "extreme_number":
                res["wrong"].append("load_model accepted a number outside the float range")
            if miss and not any("not loaded" in w or "missing" in w for w in warnings):
                res["wrong"].append(f"load: {miss} faces missing without a warning")
            if nf < orig and not miss and declared >= orig:
                res["wrong"].append(f"load: {nf} faces of {orig}, file declares {declared}, no warning")
            if not np.isfinite(model.bounds).all():
                res["wrong"].append("load: non-finite bounds")
            try:
                prep = sv.prepare(model, spacing=model.size / 20)
                res["prepare"] = "ok"
                if miss:
                    res["wrong"].append(f"prepare accepted a model with {miss} faces missing")
                if prep.n_points < 1:
                    res["wrong"].append("prepare: no model points")
            except IncompleteModelError:
                res["prepare"] = "IncompleteModelError" + ("" if miss else " (at prepare)")
        except BaseException as exc:  # noqa: BLE001
            if isinstance(exc, KeyboardInterrupt):
                raise
            res["prepare"] = classify(exc)
        res["t_prepare"] = time.perf_counter() - t0
        watch["on"] = False
        c1, (pid1, ic1) = cpu_now()
        # CPU of this mutant: the worker, the importers reaped meanwhile, the live importer
        res["cpu"] = c1 - c0 + ic1 - (ic0 if pid1 == pid0 else 0.0)
        res["importer_mb"] = importer_hwm()
        import resource
        res["worker_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024
        out.write(json.dumps(res) + "\n")
        out.flush()


def _proc_cpu(pid):
    """CPU seconds (user + system) of a live process, from /proc; None when unreadable."""
    try:
        f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


class Worker:
    """The worker process, restarted when it dies or hangs."""

    def __init__(self, hang_s: float, mem_gb: float, nice: int, warm: Path):
        self.hang_s, self.mem_gb, self.nice, self.warm = hang_s, mem_gb, nice, warm
        self.proc = None
        self.starts = 0
        self.warm_s: list[float] = []

    def _start(self):
        import resource

        lim = int(self.mem_gb * 2**30)

        def limit():
            resource.setrlimit(resource.RLIMIT_AS, (lim, lim))

        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
                   NUMBA_NUM_THREADS="1")
        cmd = (["nice", "-n", str(self.nice)] if self.nice else []) + [
            sys.executable, os.path.abspath(__file__), "--worker", "--hang-s", str(self.hang_s)]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, env=env, preexec_fn=limit,
                                     text=True, bufsize=1)
        self.starts += 1
        self.proc.stdin.write(f"{self.warm}\n")
        self.proc.stdin.flush()
        t0 = time.monotonic()
        ready = self.proc.stdout.readline()  # no time limit: numba may compile on a busy machine
        self.warm_s.append(time.monotonic() - t0)
        if not ready or json.loads(ready)["ready"] != "ok":
            raise RuntimeError(f"the fuzz worker did not start: {ready!r}")

    def run(self, req: dict) -> dict:
        import select

        if self.proc is None or self.proc.poll() is not None:
            self._start()
        try:
            self.proc.stdin.write(json.dumps(req) + "\n")
            self.proc.stdin.flush()
        except OSError:
            pass
        # a hang of the worker itself (prepare runs in it): over 2 x hang_s of its CPU on one
        # mutant (info + prepare); the wall clock is only a backstop (a loaded machine)
        wall_limit = 2 * max(WALL_FACTOR * self.hang_s, 600.0) + 60
        t0, c0 = time.monotonic(), _proc_cpu(self.proc.pid)
        while True:
            ready, _, _ = select.select([self.proc.stdout], [], [], 1.0)
            if ready:
                break
            c = _proc_cpu(self.proc.pid)
            if (c is not None and c0 is not None and c - c0 > 2 * self.hang_s) \
                    or time.monotonic() - t0 > wall_limit:
                self.kill()
                return {"info": "PARENT HANG", "prepare": "PARENT HANG", "wrong": []}
        line = self.proc.stdout.readline()
        if not line:
            status = self.proc.wait()
            self.proc = None
            return {"info": f"PARENT CRASH ({status})", "prepare": f"PARENT CRASH ({status})",
                    "wrong": []}
        return json.loads(line)

    def kill(self):
        if self.proc is not None:
            self.proc.kill()  # its importer child sees its stdin close and exits
            self.proc.wait()
            self.proc = None

    def close(self):
        if self.proc is not None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.kill()
            self.proc = None


# ------------------------------------------------------------------------------ the run
def original_faces(worker: Worker, sources: dict) -> dict[str, int]:
    out = {}
    for name, path in sources.items():
        from shapeverify.cad.face_count import declared_faces  # text only, no OpenCASCADE

        out[name] = declared_faces(path, fmt_of(path))[0]
    return out


def mutants(sources: dict, n: int, seed: int):
    """Yield (i, source name, damage name, bytes) for n mutants, round robin over the files and
    damages, each seeded by (seed, i)."""
    names = sorted(sources)
    datas = {k: Path(v).read_bytes() for k, v in sources.items()}
    for i in range(n):
        name = names[i % len(names)]
        damage = DAMAGE[(i // len(names)) % len(DAMAGE)]
        rng = np.random.default_rng([seed, i])
        try:
            data = damage(datas[name], fmt_of(name), rng)
        except (ValueError, IndexError, AttributeError):  # no place for this damage in the file
            data = flip_bytes(datas[name], fmt_of(name), rng)
            damage = flip_bytes
        yield i, name, damage.__name__, data


def run(n: int, seed: int, hang_s: float, mem_gb: float, nice: int, budget_s: float | None,
        workdir: Path, shared: bool = True, progress=None, partial=None) -> dict:
    """Run up to n mutants (or until budget_s); return the tallies (see :func:`write_results`).
    ``progress(done, wall, per, wrong, bugs)`` is called every 100 mutants, ``partial(result)``
    every 50."""
    sources = make_sources(workdir / "src", shared=shared)
    orig = original_faces(None, sources)
    worker = Worker(hang_s, mem_gb, nice, warm=sources[sorted(sources)[0]])
    per = collections.Counter()
    per_damage = collections.defaultdict(collections.Counter)
    wrong, bugs, times, mems = [], [], [], []
    t_start = time.monotonic()
    done = 0
    mdir = workdir / "mutants"
    mdir.mkdir(exist_ok=True)
    import resource
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu0 = ru0.ru_utime + ru0.ru_stime
    cpu = [float("nan")]

    def result():
        return dict(n=done, wall=time.monotonic() - t_start, per=per, per_damage=per_damage,
                    wrong=wrong, bugs=bugs, times=times, mems=mems,
                    sources={k: orig[k] for k in sources}, worker_starts=worker.starts,
                    warm_s=worker.warm_s, mutant_dir=str(mdir), cpu_s=cpu[0])

    try:
        for i, name, damage, data in mutants(sources, n, seed):
            if budget_s is not None and time.monotonic() - t_start > budget_s:
                break
            path = mdir / f"m{i:05d}-{damage}{Path(name).suffix}"
            path.write_bytes(data)
            t0 = time.monotonic()
            res = worker.run({"path": str(path), "orig_faces": orig[name], "damage": damage})
            dt = time.monotonic() - t0
            done += 1
            key = f"info: {res['info']} | prepare: {res['prepare']}"
            per[key] += 1
            per_damage[damage][res["prepare"].split(" (")[0].split(":")[0]] += 1
            times.append((dt, res.get("t_info", 0.0), res.get("t_prepare", 0.0), path.name,
                          res.get("cpu", float("nan"))))
            mems.append((res.get("importer_mb", 0), res.get("worker_mb", 0), path.name))
            keep = False
            if res["wrong"]:
                wrong.append((path.name, name, res["wrong"]))
                keep = True
            if any(str(res[k]).startswith(("BUG", "PARENT", "importer timeout", "importer hang", "memory"))
                   for k in ("info", "prepare")):
                bugs.append((path.name, name, res["info"], f"{res['prepare']} (CPU {res.get('cpu', float('nan')):.1f} s)"))
                keep = True
            if not keep:
                path.unlink()
            if progress and done % 100 == 0:
                progress(done, time.monotonic() - t_start, per, wrong, bugs)
            if partial and done % 50 == 0:
                partial(result())
    finally:
        worker.close()
    import resource
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)  # the workers and their importers, reaped
    cpu[0] = ru.ru_utime + ru.ru_stime - cpu0
    return result()


def write_results(r: dict, path: Path, command: str, seed: int, hang_s: float, mem_gb: float):
    times = sorted(r["times"], reverse=True)
    lines = [
        "# CAD fuzz run (issue 33): mutated STEP/IGES files through `info` and `prepare`",
        "",
        f"Command: `{command}`  ",
        f"Seed {seed}; time limit {hang_s:g} s per import (importer killed after it: a hang); "
        f"worker and importer address space limited to {mem_gb:g} GB (`resource.setrlimit`); "
        "worker under `nice -n 10`, one import at a time (1 CPU).",
        "",
        f"**{r['n']} mutants in {r['wall']:.0f} s wall ({r['n'] / max(r['wall'], 1e-9):.2f} "
        f"mutants/s)**; worker processes started: {r['worker_starts']} (warm-up of each: import "
        f"and prepare a clean file, numba compiling: "
        f"{', '.join(f'{x:.0f}' for x in r['warm_s'][:5])} s wall, inside the total)."
        + (" **Partial: the run is still going.**" if r.get("partial") else ""),
        "",
        (f"CPU time of the workers and importers (user + system, `getrusage`): {r['cpu_s']:.0f} s, "
         f"{r['cpu_s'] / max(r['n'], 1):.3f} s per mutant (the machine is shared: wall time "
         "is mostly waiting for a core at nice 10)." if np.isfinite(r.get("cpu_s", np.nan)) else
         "CPU time: counted when the run ends."),
        "",
        "Sources (faces declared): " + ", ".join(f"`{k}` ({v})" for k, v in r["sources"].items()),
        "",
        "| check | count |",
        "|---|---|",
        f"| parent crashes (the process running info/prepare died) | "
        f"{sum(v for k, v in r['per'].items() if 'PARENT CRASH' in k)} |",
        f"| parent hangs (over {2 * hang_s:g} s of the worker's CPU on one mutant) | "
        f"{sum(v for k, v in r['per'].items() if 'PARENT HANG' in k)} |",
        f"| importer hangs (over {hang_s:g} s of CPU on one import, killed by the watchdog) | "
        f"{sum(v for k, v in r['per'].items() if 'importer hang' in k)} |",
        f"| imports stopped by the wall-clock backstop ({max(WALL_FACTOR * hang_s, 600.0):g} s) | "
        f"{sum(v for k, v in r['per'].items() if 'importer timeout' in k)} |",
        f"| memory limit hit (MemoryError) | {sum(v for k, v in r['per'].items() if 'memory' in k)} |",
        f"| exceptions that are not input errors (bugs) | "
        f"{sum(v for k, v in r['per'].items() if 'BUG' in k)} |",
        f"| silently wrong (see the oracle in `benchmarks/fuzz_cad.py`) | {len(r['wrong'])} |",
        f"| importer crashes (contained: CADImportError naming the file) | "
        f"{sum(v for k, v in r['per'].items() if 'importer crashed' in k)} |",
        "",
        "## Outcomes (info | prepare)",
        "",
        "| outcome | mutants |",
        "|---|---|",
    ]
    lines += [f"| {k} | {v} |" for k, v in r["per"].most_common()]
    lines += ["", "## Outcome of `prepare` per damage", "", "| damage | outcomes |", "|---|---|"]
    for d, c in sorted(r["per_damage"].items()):
        lines.append(f"| {d} | " + ", ".join(f"{k} {v}" for k, v in c.most_common()) + " |")
    lines += ["", "## Slowest mutants (wall s for info + prepare; info s, prepare s)", ""]
    lines += [f"- `{p}`: {t:.2f} s ({ti:.2f} + {tp:.2f}; CPU {c:.2f} s)" for t, ti, tp, p, c in times[:8]]
    if times:
        all_t = np.array([t[0] for t in times])
        cpus = np.array([t[4] for t in times])
        lines += ["", f"Wall per mutant: median {np.median(all_t):.3f} s, 99th percentile "
                      f"{np.percentile(all_t, 99):.2f} s, max {all_t.max():.2f} s (the machine is "
                      "shared: wall time includes waiting for a core at nice 10, and the importer's "
                      "start after each crash or 64 imports).",
                  f"CPU per mutant (worker + importer): median {np.nanmedian(cpus):.3f} s, 99th "
                  f"percentile {np.nanpercentile(cpus, 99):.2f} s, max {np.nanmax(cpus):.2f} s; "
                  f"mutants over 60 s of CPU: {int(np.sum(cpus > 60))}."]
        lines += ["", "Slowest mutants by CPU:", ""]
        lines += [f"- `{p}`: CPU {c:.2f} s (wall {t:.2f} s)"
                  for t, ti, tp, p, c in sorted(times, key=lambda x: -np.nan_to_num(x[4]))[:5]]
    mem_i = max((m[0] for m in r["mems"]), default=0)
    mem_w = max((m[1] for m in r["mems"]), default=0)
    lines += ["", f"Peak resident memory: importer {mem_i} MB, worker {mem_w} MB "
                  f"(limit {mem_gb:g} GB of address space)."]
    if r["wrong"]:
        lines += ["", "## Silently wrong", ""]
        lines += [f"- `{p}` (from `{s}`): {'; '.join(w)}" for p, s, w in r["wrong"][:30]]
    if r["bugs"]:
        lines += ["", "## Crashes, hangs, bugs", ""]
        lines += [f"- `{p}` (from `{s}`): info {a}; prepare {b}" for p, s, a, b in r["bugs"][:30]]
    lines.append("")
    path.write_text("\n".join(lines))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-n", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--hang-s", type=float, default=60.0)
    ap.add_argument("--mem-gb", type=float, default=2.0)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--budget-s", type=float, default=None, help="stop after this many seconds")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results_fuzz.md")
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        return _worker_main(a.hang_s)
    command = "python benchmarks/fuzz_cad.py " + " ".join(shlex.quote(x) for x in (argv or sys.argv[1:]))
    workdir = a.workdir or Path(tempfile.mkdtemp(prefix="fuzz-cad-"))

    def progress(done, wall, per, wrong, bugs):
        print(f"{done} mutants, {wall:.0f} s, {done / wall:.2f}/s, wrong {len(wrong)}, "
              f"bugs/hangs/crashes {len(bugs)}", flush=True)

    def partial(r):
        write_results(dict(r, partial=True), a.out, command, a.seed, a.hang_s, a.mem_gb)

    r = run(a.n, a.seed, a.hang_s, a.mem_gb, a.nice, a.budget_s, workdir, progress=progress,
            partial=partial)
    write_results(r, a.out, command, a.seed, a.hang_s, a.mem_gb)
    print(a.out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
