"""The verdict's reasons keep three significant digits on any part size (issue 32 item 4).

An independent render of the 1.855 mm wavy cube (``benchmarks/check_independent_scans.py``)
failed with "material added: 348 points, 0.0 mm², extreme +0.009 mm at (0.8, 0.0, 0.3) mm", the
40 m hammer with "6996473.2 mm² ... at (-2316.3, 18882.8, -5006.9) mm": the reports used
:mod:`shapeverify.quantities` already, the reasons (regions, coverage, floating surfaces) did not.
"""
from __future__ import annotations

import numpy as np

from shapeverify.inspection.regions import DefectRegion


def _region(area, extreme, centroid):
    c = np.asarray(centroid, float)
    return DefectRegion(n=348, area=area, extreme=extreme, extreme_raw=extreme, centroid=c,
                        extreme_point=c, faces=(1,), side="above" if extreme > 0 else "below",
                        indices=np.arange(3))


def test_a_1_mm_parts_region_reads_in_micrometres():
    text = _region(0.0123, 0.00927, (0.8123, 0.0331, 0.305)).describe()
    assert "0.0123 mm²" in text and "extreme +9.27 µm" in text
    assert "(0.812, 0.033, 0.305) mm" in text and "0.0 mm²" not in text
    assert "3.4 µm²" in _region(3.4e-6, -0.004, (0.001, 0.002, 0.0)).describe()


def test_a_40_m_parts_region_reads_in_metres():
    text = _region(6_996_473.2, -169.08, (-2316.3, 18882.8, -5006.9)).describe()
    assert "7 m²" in text and "extreme -169 mm" in text and "(-2.3, 18.9, -5) m" in text


def test_the_coverage_gap_and_the_incomplete_reason_keep_their_digits():
    from shapeverify.inspection.coverage import Coverage

    cov = Coverage.__new__(Coverage)
    object.__setattr__(cov, "gaps", [{"area": 0.0042, "centroid": [0.81, 0.02, 0.3],
                                      "faces": [2]}])
    text = cov.describe_gap()
    assert "4,200 µm²" in text and "(0.81, 0.02, 0.3) mm" in text
