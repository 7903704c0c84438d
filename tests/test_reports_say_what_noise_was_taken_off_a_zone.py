"""A flatness corrected for its noise (:mod:`shapeverify.characteristics.zone_noise`) read
0.04 in the reports where the points span 0.15, with nothing to say why: the terminal, HTML
and PDF tables now print the points' own zone and the noise's expected part under the value,
the numbers of the result's ``details``."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fcf_synthetic import synthetic_plan_result
from shapeverify.characteristics.zone_noise import corrected_width, noise_note

PLAN = """units: mm
alignment: {type: best_fit}
characteristics:
  - {name: FLAT, type: flatness, faces: [face:0], tol: 0.1}
"""


def _flatness_result():
    """A plan result whose flatness is a real correction: a 100 x 50 mm face at 1 mm, tilted,
    0.02 mm noise."""
    rng = np.random.default_rng(4)
    x, y = np.meshgrid(np.arange(0, 100.0), np.arange(0, 50.0))
    z = 0.0005 * x + rng.normal(0, 0.02, x.shape)
    X = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    v = X[:, 2] - 0.0005 * X[:, 0]
    width = float(np.ptp(v))
    value, u, details = corrected_width(width, X, [0.0, 0.0, 1.0], 0.02)
    pr = synthetic_plan_result(PLAN)
    c = dataclasses.replace(pr.characteristics[0], measured=value, deviation=value,
                            uncertainty=u, details=details)
    return dataclasses.replace(pr, characteristics=(c,)), c


def test_noise_note_gives_the_points_zone_and_the_part_taken_off():
    pr, c = _flatness_result()
    note = noise_note(c.details)
    w, b = c.details["zone_of_points"], c.details["noise_bias"]
    assert w > 0.1 and b > 0.05 and c.measured == pytest.approx(w - b)
    assert note == f"points {w:.4f} − noise {b:.4f}"


def test_html_pdf_and_terminal_tables_print_the_note():
    pytest.importorskip("plotly")
    from rich.console import Console

    import shapeverify.cli as cli
    from shapeverify.characteristics.pdf import _table_entries
    from shapeverify.report.html import render_html
    from test_report_layout import _inspected

    pr, c = _flatness_result()
    note = noise_note(c.details)
    res, _ = _inspected(100.0, "NOISE", dent=False)
    res = dataclasses.replace(res, plan=pr, characteristics=pr.characteristics)
    assert note in render_html(res, None, max_points=500)
    rows = [e[1][0] for e in _table_entries(pr) if e[0] == "row"]
    assert rows[0][3].splitlines()[1:] == noise_note(c.details, sep="\n").splitlines()
    console = Console(record=True, width=200)
    old = cli.out
    cli.out = console
    try:
        cli._print_result(res)
    finally:
        cli.out = old
    assert note in console.export_text()
