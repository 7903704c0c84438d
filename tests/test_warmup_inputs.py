"""The warm-up covers the scans other programs hand over (issue 32, item 3): a read-only array
(``np.frombuffer``, a memory map) made numba compile 2 kernels again on the first inspection
after ``make demo``'s warm-up; float32 and Fortran-ordered scans must not compile either."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

CHECK = r"""
import sys
import numpy as np
import shapeverify as sv
from shapeverify.warmup import compile_notices

prep = sv.load_prepared(sys.argv[1])
points = sv.read_points(sys.argv[2])
sv.inspect(prep, points, tolerance=0.2)
ro = np.frombuffer(points.tobytes(), dtype=np.float64).reshape(-1, 3)     # read-only
assert not ro.flags.writeable
counts = []
for variant in (ro, points.astype(np.float32), np.asfortranarray(points)):
    with compile_notices(lambda text: None) as stats:
        sv.inspect(prep, variant, tolerance=0.2)
    counts.append(stats["n"])
print("compiled", counts)
"""


def test_after_the_warm_up_read_only_float32_and_fortran_scans_compile_nothing(tmp_path):
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.io.points import write_ply
    from shapeverify.nearest import prepare
    from shapeverify.simulate import virtual_scan
    from shapeverify.warmup import input_variants

    model = load_model(example_part_step(tmp_path / "panel.step"))
    prepare(model, spacing=3.0).save(tmp_path / "panel.svm")
    write_ply(tmp_path / "scan.ply", virtual_scan(model, pixel=4.0, noise=0.02, rng=3).scan)
    input_variants(tmp_path / "panel.svm", tmp_path / "scan.ply")      # the warm-up's step
    # a new process, as the user's next command: everything comes from numba's cache
    proc = subprocess.run([sys.executable, "-c", CHECK, str(tmp_path / "panel.svm"),
                           str(tmp_path / "scan.ply")], capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "compiled [0, 0, 0]" in proc.stdout, proc.stdout
