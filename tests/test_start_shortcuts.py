"""The command line's start shortcuts (``shapeverify._start_shortcuts``, issue 32 item 7): a
cached numba kernel loads without numba's registries and answers as the compiled one; a kernel
not in the cache still compiles; scipy.spatial imported without the docstring rewrite works as
before and leaves scipy's ``FunctionDoc`` in place.  Each in a fresh interpreter (this test
process has loaded numba's registries already), the kernel in a module of its own under
``tmp_path`` so that its cache is this test's."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

KERNEL = '''
import numpy as np
from numba import njit


@njit(cache=True)
def nearest_index(points, q):
    best, k = np.inf, -1
    for i in range(points.shape[0]):
        d = 0.0
        for j in range(points.shape[1]):
            d += (points[i, j] - q[j]) ** 2
        if d < best:
            best, k = d, i
    return k, np.sqrt(best)
'''

RUN = r'''
import json, sys
import numpy as np
if sys.argv[1] == "deferred":
    from shapeverify._start_shortcuts import defer_numba_registries
    assert defer_numba_registries()
import kern
import numba.core.base  # noqa: F401 - registers numba's llvm-lock events
from llvmlite.binding import ffi
callbacks = list(ffi.lib._lock._cblist)
rng = np.random.default_rng(3)
P, q = rng.normal(size=(500, 3)), rng.normal(size=3)
k, d = kern.nearest_index(P, q)
registries = "numba.typed.typeddict" in sys.modules
out = {"k": int(k), "d": float(d), "registries_after_hit": registries}
# a signature not in the cache: numba compiles it (float32 points)
k32, _ = kern.nearest_index(P.astype(np.float32), q.astype(np.float32))
out["k32"] = int(k32)
out["callbacks_kept"] = ffi.lib._lock._cblist == callbacks and len(callbacks) > 0
out["hits"] = sum(kern.nearest_index.stats.cache_hits.values())
out["misses"] = sum(kern.nearest_index.stats.cache_misses.values())
d2 = ((P - q) ** 2).sum(axis=1)
out["brute_k"], out["brute_d"] = int(np.argmin(d2)), float(np.sqrt(d2.min()))
print(json.dumps(out))
'''


def _run(tmp_path: Path, mode: str) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), str(Path(__file__).parents[1] / "src"),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", RUN, mode], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.splitlines()[-1])


def test_cached_kernel_loads_without_numba_registries_and_gives_the_same_answer(tmp_path):
    (tmp_path / "kern.py").write_text(textwrap.dedent(KERNEL))
    first = _run(tmp_path, "plain")         # compiles both signatures, caches them
    assert first["k"] == first["brute_k"] and abs(first["d"] - first["brute_d"]) < 1e-12
    deferred = _run(tmp_path, "deferred")   # both signatures from the cache
    assert deferred["hits"] == 2 and deferred["misses"] == 0
    assert not deferred["registries_after_hit"]     # the cache hit did not refresh numba
    assert (deferred["k"], deferred["d"]) == (first["k"], first["d"])
    assert deferred["k32"] == first["k32"] == first["brute_k"]
    assert deferred["callbacks_kept"]               # the llvm-lock callbacks back after loads


def test_a_cache_miss_still_compiles_with_the_registries_deferred(tmp_path):
    (tmp_path / "kern.py").write_text(textwrap.dedent(KERNEL))
    out = _run(tmp_path, "deferred")        # nothing cached: both signatures compile
    assert out["misses"] == 2 and out["hits"] == 0
    assert out["k"] == out["brute_k"] and abs(out["d"] - out["brute_d"]) < 1e-12
    assert out["k32"] == out["brute_k"]


NUMBA_CONFIG = r'''
import json, sys
from shapeverify._start_shortcuts import import_numba
import_numba()
import numba.core.config as config
before = "yaml" in sys.modules
config.reload_config()          # numba reads its environment (and a config file) again
import yaml                     # PyYAML itself, for whoever imports it next
print(json.dumps({"yaml_at_import": before, "debug_cache": config.DEBUG_CACHE,
                  "real_yaml": hasattr(yaml, "__file__") and yaml.safe_load("a: 1") == {"a": 1}}))
'''


def _numba_config(cwd: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parents[1] / "src"),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", NUMBA_CONFIG], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.splitlines()[-1])


def test_numba_imports_without_pyyaml_and_still_reads_its_config_file(tmp_path):
    # no config file: numba imported, PyYAML not (the command's start skips its 18 modules)
    (tmp_path / "plain").mkdir()
    plain = _numba_config(tmp_path / "plain")
    assert plain["yaml_at_import"] is False and plain["debug_cache"] == 0
    assert plain["real_yaml"]
    # a .numba_config.yaml in the working directory counts as with a plain ``import numba``
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / ".numba_config.yaml").write_text("debug_cache: 1\n")
    cfg = _numba_config(tmp_path / "cfg")
    assert cfg["debug_cache"] == 1 and cfg["real_yaml"]


INSPECT_IMPORTS = r'''
import json, sys
from shapeverify import cli_start
cli_start.preimport()
print(json.dumps(sorted(m for m in sys.modules if m == "yaml" or m.startswith("yaml."))))
'''


def test_the_inspect_start_does_not_import_pyyaml():
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parents[1] / "src"),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", INSPECT_IMPORTS], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout.splitlines()[-1]) == []


BARE_KDTREE = r'''
import json, sys
import numpy as np
from shapeverify._lazy import cKDTree, kdtree_class
rng = np.random.default_rng(7)
P, Q = rng.normal(size=(2000, 3)), rng.normal(size=(50, 3))
tree = cKDTree(P)
d, i = tree.query(Q, k=3)
heavy = sorted(m for m in ("scipy.spatial", "scipy.sparse", "scipy.linalg", "scipy._lib._util",
                           "scipy._lib._array_api", "numpy.f2py", "numpy.testing")
               if m in sys.modules)
D = np.linalg.norm(Q[:, None, :] - P[None, :, :], axis=2)
bi = np.argsort(D, axis=1)[:, :3]
# what the placeholders stood for, used after the load: scipy.sparse's matrices
coo = tree.sparse_distance_matrix(cKDTree(Q), 0.5, output_type="coo_matrix")
dense = np.where(D.T <= 0.5, D.T, 0.0)
import scipy.spatial
print(json.dumps({"heavy": heavy, "same_index": bool((i == bi).all()),
                  "dist_err": float(np.abs(d - np.take_along_axis(D, bi, 1)).max()),
                  "coo_err": float(np.abs(coo.toarray() - dense).max()),
                  "coo_type": type(coo).__name__,
                  "same_class": scipy.spatial.cKDTree is kdtree_class()
                                and scipy.spatial._ckdtree.cKDTree is kdtree_class(),
                  "kdtree_subclass": issubclass(scipy.spatial.KDTree, kdtree_class())}))
'''


def test_the_bare_kdtree_queries_as_brute_force_without_scipy_spatial_and_is_scipys_class():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parents[1] / "src"),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", BARE_KDTREE], env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["heavy"] == []       # the tree came without scipy.spatial, sparse, linalg
    assert out["same_index"] and out["dist_err"] < 1e-12
    assert out["coo_type"] == "coo_matrix" and out["coo_err"] < 1e-12
    assert out["same_class"] and out["kdtree_subclass"]


INSPECT_SCIPY = r'''
import json, sys
from shapeverify import cli_start
cli_start.preimport()
import numpy as np
from numba import njit
@njit
def smallest_eigenvalue(S):
    w, _ = np.linalg.eigh(S)
    return w[0]
S = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]])
print(json.dumps({"heavy": sorted(m for m in ("scipy.spatial", "scipy.sparse", "scipy.linalg",
                                              "numpy.f2py") if m in sys.modules),
                  "eig_err": float(abs(smallest_eigenvalue(S) - np.linalg.eigvalsh(S)[0]))}))
import scipy.linalg
from scipy.linalg import cython_lapack
print(json.dumps({"lu": float(np.abs(scipy.linalg.lu_factor(S)[0]).max()),
                  "lapack": cython_lapack is sys.modules["scipy.linalg.cython_lapack"]}))
'''


def test_the_inspect_start_imports_no_scipy_package_and_numba_still_finds_lapack():
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parents[1] / "src"),
                                         env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", INSPECT_SCIPY], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    first, later = (json.loads(line) for line in proc.stdout.splitlines()[-2:])
    assert first["heavy"] == []
    assert first["eig_err"] < 1e-12     # numba's eigh through the bare cython_lapack
    assert later["lapack"] and later["lu"] > 0     # scipy.linalg imports as usual afterwards
