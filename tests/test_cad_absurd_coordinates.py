"""Found by the CAD fuzz run (issue 33, ``benchmarks/fuzz_cad.py``): a finite but absurd number in a
CAD file -- ``1E+300`` in a control point -- passed the check for numbers outside the float range.

* STEP: OpenCASCADE read it; sampling the face's edges to the chord tolerance then subdivided
  without end (the process was OOM-killed; under a 2 GB limit a MemoryError).
* IGES: ``info`` showed a model of size ``inf``, ``prepare`` failed with "spacing must be a finite
  number > 0 (mm), got inf", naming no file.

Now a face with a control point beyond +-1e12 mm is refused before its edges are sampled, and a
model (or summary) whose bounds are not finite or beyond 1e12 mm is a ``CADImportError`` naming
the file.  The import runs in a child process with a 2 GB address-space limit, so that a
regression fails here instead of exhausting the machine.
"""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shapeverify.cad.number_check import check_extent
from shapeverify.errors import CADImportError

pytest.importorskip("OCP")

SRC = str(Path(__file__).resolve().parents[1] / "src")

_CHILD = r"""
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from shapeverify.cad import occ_import
from shapeverify.cad.occ_summary import read_summary
for f in (lambda p: occ_import.read_cad(p, isolated=False), read_summary):
    try:
        f(sys.argv[1])
        print("ACCEPTED")
    except MemoryError:
        print("MEMORY")
    except Exception as e:
        print(type(e).__name__, str(e).replace("\n", " "))
"""


def _step_with_control_point(tmp_path, value: bytes) -> Path:
    from shapeverify.cad.examples import example_part_step

    data = example_part_step(tmp_path / "panel.step").read_bytes()
    pts = list(re.finditer(rb"CARTESIAN_POINT\('[^']*',\((-?\d+\.\d*(?:E[+-]?\d+)?)", data))
    m = pts[len(pts) // 2]                        # a control point of the panel's B-spline
    bad = tmp_path / "bad.step"
    bad.write_bytes(data[:m.start(1)] + value + data[m.end(1):])
    return bad


def _refusals(bad: Path) -> list[str]:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(bad)], capture_output=True, text=True,
                         timeout=300, env={"PYTHONPATH": SRC, "PATH": "/usr/bin:/bin"})
    lines = [ln for ln in out.stdout.splitlines() if ln.split(" ")[0] in
             ("ACCEPTED", "MEMORY", "CADImportError", "EmptyModelError", "ValueError")]
    assert len(lines) == 2, (out.stdout[-2000:], out.stderr[-2000:])
    return lines                                   # read_cad, then info's summary


def test_fuzz_1e300_control_point_is_refused_not_sampled_without_end(tmp_path):
    # refused by the number check (its square overflows a double) before OpenCASCADE reads it
    for ln in _refusals(_step_with_control_point(tmp_path, b"1.E+300")):
        assert ln.startswith("CADImportError"), ln
        assert "bad.step" in ln and "'1.E+300'" in ln and "too large" in ln, ln


def test_fuzz_1e100_control_point_is_refused_before_its_edges_are_sampled(tmp_path):
    # a number a double squares safely, absurd for a length: the face check refuses it
    for ln in _refusals(_step_with_control_point(tmp_path, b"1.E+100")):
        assert ln.startswith("CADImportError"), ln
        assert "bad.step" in ln and "1e+100" in ln, ln


def _panel_iges(path: Path) -> Path:
    """The example panel written to IGES (here, as tests/test_fuzz_cad.py does: only the
    imports of damaged files run in a child)."""
    from OCP.IGESControl import IGESControl_Writer

    from shapeverify.cad.examples import panel_shape

    w = IGESControl_Writer("MM", 0)
    w.AddShape(panel_shape())
    w.ComputeModel()
    assert w.Write(str(path))
    return path


def test_fuzz_1e300_in_an_iges_trimming_curve_is_refused_not_a_two_minute_hang(tmp_path):
    """The CAD fuzz run's one hang (seed 20261207, mutant 485): ``1E+300`` for a control point
    of a B-spline curve (entity 126) in the panel's IGES kept the importer busy for over 120 s
    of CPU (``info`` did not return in 120 s).  Refused now in well under a second, naming
    the file, the line and the token."""
    src = _panel_iges(tmp_path / "panel.igs")
    lines = src.read_bytes().split(b"\n")
    k = next(i for i, ln in enumerate(lines) if ln[72:73] == b"P" and ln[:4] == b"126,")
    for i in range(k + 1, len(lines)):             # a control point of that curve
        m = re.search(rb",(0\.\d{6,})", lines[i][:64])
        if m:
            tok = b"1E+300".rjust(len(m.group(1)))
            lines[i] = lines[i][:m.start(1)] + tok + lines[i][m.end(1):]
            break
    bad = tmp_path / "bad.igs"
    bad.write_bytes(b"\n".join(lines))
    from shapeverify.cad.number_check import check_numbers

    with pytest.raises(CADImportError, match=r"bad\.igs: line \d+ holds '1E\+300'.*too large"):
        check_numbers(bad, "iges")
    for ln in _refusals(bad):
        assert ln.startswith("CADImportError") and "bad.igs" in ln, ln


def test_fuzz_large_but_sane_control_point_still_loads(tmp_path):
    # 1e5 mm (100 m) is a big part, not a damaged number: read as before
    bad = _step_with_control_point(tmp_path, b"1.E+5")
    out = subprocess.run([sys.executable, "-c", _CHILD, str(bad)], capture_output=True, text=True,
                         timeout=300, env={"PYTHONPATH": SRC, "PATH": "/usr/bin:/bin"})
    assert out.stdout.count("ACCEPTED") == 2, (out.stdout[-2000:], out.stderr[-2000:])


@pytest.mark.parametrize("hi", [(1.0, 2.0, 2.78e299), (1.0, np.inf, 3.0), (np.nan, 1.0, 1.0),
                                (1.5e12, 0.0, 0.0)])
def test_fuzz_model_bounds_beyond_1e12_mm_are_refused(hi):
    with pytest.raises(CADImportError, match=r"m35\.igs: the model reaches a coordinate"):
        check_extent("m35.igs", (0.0, 0.0, 0.0), hi)


def test_fuzz_model_bounds_of_a_real_part_pass():
    check_extent("hammer.iges", (-24717.0, -300.0, 0.0), (24717.0, 300.0, 1000.0))
