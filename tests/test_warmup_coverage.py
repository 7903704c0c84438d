"""After ``python -m shapeverify.warmup`` nothing compiles (issue 32 item 3): the first inspection
of a new part compiled for 95 s after ``make demo``'s warm-up, the first fringe analysis for
18 s.  Here the warm-up runs on a fresh numba cache directory, then each command runs on new
inputs of its own (other sizes, other data, text files, float32 and Fortran-ordered arrays: an
F-ordered phase map compiled 2 kernels), as a user's first commands would, and must compile
nothing: no ``numba:compile`` event in the command's process
(numba fires it only when it compiles, not when it loads from the cache), no cache miss in any
kernel's statistics, and no file written to the cache directory (which also covers the CAD
importer's child process)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

RUNNER = r"""
import json, sys
from numba.core import event

compiled = []


class _Listener(event.Listener):
    def on_start(self, ev):
        d = ev.data.get("dispatcher")
        compiled.append(getattr(d, "__qualname__", None) or repr(d))

    def on_end(self, ev):
        pass


event.register("numba:compile", _Listener())
report, sys.argv = sys.argv[1], ["shapeverify", *sys.argv[2:]]
from shapeverify.cli_start import main

try:
    code = main() or 0
except SystemExit as exc:
    code = exc.code
misses = set()
for name, mod in list(sys.modules.items()):
    if not name.startswith("shapeverify") or mod is None:
        continue
    for attr, obj in list(vars(mod).items()):
        stats = getattr(obj, "stats", None)
        if hasattr(obj, "py_func") and hasattr(stats, "cache_misses"):
            if sum(stats.cache_misses.values()):
                misses.add(f"{name}.{attr}")
with open(report, "w") as f:
    json.dump({"code": code, "compiled": compiled, "misses": sorted(misses)}, f)
"""


def _cache_state(cache: Path) -> dict:
    return {str(p.relative_to(cache)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in cache.rglob("*") if p.is_file()}


def _files(d: Path) -> dict:
    import hashlib

    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file()}


def _warm_up_into(root: Path) -> None:
    """``python -m shapeverify.warmup`` with a fresh, empty numba cache directory
    ``root/numba`` (and summary cache ``root/summaries``)."""
    cache = root / "numba"
    cache.mkdir(parents=True)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "SHAPEVERIFY_CACHE_DIR": str(root / "summaries"), "COLUMNS": "120"}
    proc = subprocess.run([sys.executable, "-m", "shapeverify.warmup", "--quiet"], env=env,
                          capture_output=True, text=True, timeout=3600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]


def snapshot_dir() -> Path:
    """Where ``make``'s set-up keeps its snapshot of the warm-up's cache (``python -m
    shapeverify.warmup --snapshot``): ``$SHAPEVERIFY_WARMUP_SNAPSHOT``, else the checkout's
    ``.venv/warmup-snapshot``."""
    env = os.environ.get("SHAPEVERIFY_WARMUP_SNAPSHOT")
    return Path(env) if env else Path(__file__).resolve().parents[1] / ".venv" / "warmup-snapshot"


def _usable_snapshot(snap: Path, stamp: str) -> dict | None:
    """The manifest of the snapshot ``snap`` if it is of these sources (``stamp``) and its files
    are the ones it lists, bit for bit; else None."""
    try:
        manifest = json.loads((snap / "manifest.json").read_text())
    except (OSError, ValueError):
        return None
    if manifest.get("stamp") != stamp or not manifest.get("files"):
        return None
    return manifest if _files(snap / "numba") == manifest["files"] else None


@pytest.fixture(scope="module")
def warmed(tmp_path_factory):
    """A numba cache directory holding what the warm-up, and only the warm-up, wrote to an empty
    cache, in a folder of its own, and the environment that uses it.

    The warm-up on an empty cache is minutes of compiling (216 s of the fresh clone's 21-minute
    suite), and ``make test`` has just done it: its set-up runs ``python -m shapeverify.warmup
    --snapshot .venv/warmup-snapshot``, which copies the cache files it wrote, when the cache
    held none before it, with the sources' stamp and the files' SHA-256 (before any test can add
    kernels to the cache).  A snapshot of these sources (:func:`sources_stamp`: their bytes,
    sizes, mtimes, folder, numba, Python) whose files are those it lists is copied here.  Else
    (pytest run by hand, sources edited since): the warm-up runs on a fresh, empty cache
    directory; its result is kept, untouched, in the suite's cache (tests/model_cache.py's
    folder of this code version, keyed by the same stamp) with the list of its files and their
    SHA-256, and each run gets a copy (a kept result whose files differ from its list is made
    again).  Either way the commands below use a copy of exactly what a warm-up wrote to an
    empty cache (and must not add to it)."""
    import shutil

    from model_cache import _locked, cache_root

    from shapeverify.warmup import sources_stamp

    stamp = sources_stamp()
    root = tmp_path_factory.mktemp("warm")
    cache = root / "numba"
    snap = snapshot_dir()
    manifest = _usable_snapshot(snap, stamp)
    if manifest is not None:
        shutil.copytree(snap / "numba", cache)
        assert _files(cache) == manifest["files"]
    else:
        keep = cache_root() / f"warmup-{stamp[:24]}"
        listed = keep / "files.json"
        with _locked(keep):
            if not (listed.is_file()
                    and json.loads(listed.read_text()) == _files(keep / "made")):
                shutil.rmtree(keep, ignore_errors=True)
                tmp = keep.with_name(f"{keep.name}.{os.getpid()}")
                shutil.rmtree(tmp, ignore_errors=True)
                _warm_up_into(tmp / "made")
                listed_tmp = tmp / "files.json"
                listed_tmp.write_text(json.dumps(_files(tmp / "made")))
                os.replace(tmp, keep)
        shutil.copytree(keep / "made", root, dirs_exist_ok=True)
        assert _files(root) == json.loads(listed.read_text())
    assert any(cache.rglob("*.nbc")), "the warm-up wrote nothing to the fresh cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "SHAPEVERIFY_CACHE_DIR": str(root / "summaries"), "COLUMNS": "120"}
    return root, cache, env


def _inputs(d: Path) -> dict:
    """New inputs for every command: not the warm-up's files, the same kinds of data."""
    from shapeverify._warmup_commands import PLAN, element_points
    from shapeverify.cad.examples import PANEL_HOLE, example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.phase import wrap
    from shapeverify.simulate import ScanEffects, virtual_scan
    from shapeverify.simulate.hologram import dual_wavelength_holograms, grooved_plate

    step = example_part_step(d / "part.step")
    scan = virtual_scan(load_model(step), pixel=2.5, noise=0.03,
                        effects=ScanEffects(outlier_fraction=0.02,
                                            dents=[(0.5, 12.0)]), motion=(2.0, 3.0), rng=77).scan
    np.savetxt(d / "scan.xyz", scan.astype(np.float32), fmt="%.5f")      # a text scan
    x, y, _ = PANEL_HOLE
    (d / "plan.yaml").write_text(PLAN.format(x=x, y=y).replace("tol: 0.4", "tol: 0.5"))
    yy, xx = np.mgrid[0:57, 0:33]
    np.save(d / "psi.npy", wrap(0.01 * (xx - 10.0) ** 2 - 0.02 * yy * xx).astype(np.float32))
    # written in Fortran order (MATLAB, np.asfortranarray): np.load keeps the order
    np.save(d / "psiF.npy", np.asfortranarray(wrap(0.008 * (xx - 12.0) ** 2 + 0.03 * yy)))
    l1, lam, pitch = 632.8e-6, 0.3, 0.04
    l2 = l1 * lam / (lam - l1)
    depth, _ = grooved_plate((72, 88), pitch, 0.8, 0.3)
    h1, h2 = dual_wavelength_holograms(depth, l1, l2, pixel_pitch=pitch, noise=0.01, bits=12,
                                       rng=11)
    np.save(d / "h1.npy", h1.intensity.astype(np.uint16))
    np.save(d / "h2.npy", h2.intensity.astype(np.uint16))
    np.save(d / "ref.npy", depth)
    t = np.linspace(0.0, 2.0, 150)
    np.save(d / "curve.npy", np.column_stack([30 * np.cos(t), 30 * np.sin(t), 4 * t]))
    np.savetxt(d / "cyl.txt", element_points("cylinder", 300, rng=5) * 2.0)
    return {"step": step, "plan": d / "plan.yaml", "l1": l1, "l2": l2, "pitch": pitch}


def _commands(d: Path, inp: dict) -> list[list]:
    cmds = [
        ["info", inp["step"]],
        ["prepare", inp["step"], "-o", d / "part.svm"],
        ["info", d / "part.svm"],
        ["inspect", d / "part.svm", d / "scan.xyz", "--tolerance", "0.25", "--json",
         d / "r.json", "--report", d / "r.html", "--png", d / "r.png"],
        ["inspect", d / "part.svm", d / "scan.xyz", "--tolerance", "0.25", "--plan",
         inp["plan"], "--pdf", d / "r.pdf"],
        ["unwrap", d / "psi.npy", "-o", d / "phi.npy"],
        ["unwrap", d / "psi.npy", "-o", d / "phi_q.npy", "--method", "quality"],
        ["unwrap", d / "psiF.npy", "-o", d / "phi_wls.npy", "--method", "wls"],
        ["unwrap", d / "psiF.npy", "-o", d / "phi_lp.npy", "--method", "lp"],
        ["hologram", d / "h1.npy", d / "h2.npy", "-o", d / "depth.npy", "--lambda1",
         str(inp["l1"]), "--lambda2", str(inp["l2"]), "--reference", d / "ref.npy"],
        ["fit", d / "curve.npy", "--ctrl", "9", "-o", d / "curve.json"],
        ["fit", d / "cyl.txt", "--element", "cylinder", "--loss", "huber", "-o", d / "cyl.json"],
    ]
    try:
        import cv2
    except ImportError:
        return cmds
    from shapeverify.camera.rig import save_rig
    from shapeverify.simulate.fringes import demo_scene, fringe_images

    model, rig, T = demo_scene(150, 140)
    imgs = fringe_images(model, rig, T, period_mm=1.2, rng=9)
    cv2.imwrite(str(d / "left_cam.png"), imgs.left)
    cv2.imwrite(str(d / "right_cam.png"), imgs.right)
    save_rig(imgs.rig, d / "rig.json")
    cmds.append(["measure", d / "rig.json", d / "left_cam.png", d / "right_cam.png", "-o",
                 d / "m.ply"])
    return cmds


def test_after_the_warm_up_no_command_compiles_on_new_inputs(warmed):
    root, cache, env = warmed
    d = root / "user"
    d.mkdir()
    inp = _inputs(d)
    failures = []
    for argv in _commands(d, inp):
        before = _cache_state(cache)
        report = d / "report.json"
        proc = subprocess.run([sys.executable, "-c", RUNNER, str(report), *map(str, argv)],
                              cwd=d, env=env, capture_output=True, text=True, timeout=900)
        shown = " ".join(str(a).replace(str(d) + os.sep, "") for a in argv)
        assert report.is_file(), f"{shown}: {proc.stderr[-3000:]}"
        got = json.loads(report.read_text())
        assert got["code"] in (0, 1, 3), f"{shown} exited {got['code']}: {proc.stderr[-3000:]}"
        written = sorted(k for k, v in _cache_state(cache).items() if before.get(k) != v)
        if got["compiled"] or got["misses"] or written:
            failures.append(f"{shown}: compiled {got['compiled']}, cache misses "
                            f"{got['misses']}, cache files written {written}")
    assert not failures, "\n".join(failures)
