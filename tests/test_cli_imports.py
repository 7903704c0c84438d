"""The command line starts light (issue 32 item 7): ``import shapeverify`` and
``import shapeverify.cli`` load none of the heavy libraries (numba, scipy, matplotlib, plotly,
OpenCASCADE); each command imports what it uses when it runs.  Measured in a fresh interpreter,
since this test process has imported them all already."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("numba", "llvmlite", "scipy", "matplotlib", "plotly", "OCP", "open3d", "dask",
         "fastapi", "pydantic")

PROBE = r"""
import json, sys
for name in sys.argv[1:]:
    __import__(name)
print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))
"""


def _loaded(*modules: str) -> set[str]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *modules], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return set(json.loads(proc.stdout.splitlines()[-1]))


@pytest.mark.parametrize("modules", [("shapeverify",), ("shapeverify.cli",),
                                     ("shapeverify.cli_start",), ("shapeverify.warmup",)])
def test_importing_the_package_or_the_command_line_loads_no_heavy_library(modules):
    loaded = _loaded(*modules)
    assert "shapeverify" in loaded
    heavy = sorted(loaded.intersection(HEAVY))
    assert not heavy, f"import {', '.join(modules)} loaded {heavy}"


def test_the_public_names_still_resolve_lazily():
    # the lazy __getattr__ of the package gives the real objects
    proc = subprocess.run([sys.executable, "-c",
                           "import shapeverify as sv, sys; "
                           "assert 'numba' not in sys.modules; "
                           "f = sv.inspect; "
                           "assert f.__module__ == 'shapeverify.inspection.inspect', f; "
                           "assert callable(f) and 'numba' in sys.modules; print('ok')"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-3000:]
