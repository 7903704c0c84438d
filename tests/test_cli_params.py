"""The command line converts plain option values without pydantic, to the same values and with
the same errors as typer's pydantic conversion (issue 32 item 7: ``shapeverify.cli_params``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import List

import pytest
import typer
from typer.testing import CliRunner

from shapeverify import cli_params

VALUES = ["0.2", "-0.2", "0", "-0", "42", "-7", "123456", "1e-3", "1E3", "2.5e+2", "1e400", "-1e400", "10", "007",
          "+1", " 1", "1 ", "1_000", "0x10", "nan", "inf", "-inf", ".5", "5.", "", "abc",
          "1e", "--1", "12345678901234567890", "1.234567890123456789", "½"]
PATHS = ["panel.svm", "a b/c.ply", "-", "~/x.step", ".", "", " lead", "trail ", "é/ü.stl"]


def _both(annotation, value):
    """(fast answer or 'declined', pydantic answer or its error's text)."""
    import typer.core as core
    from typer._coercion import resolve_type_descriptor
    from typer.models import OptionInfo

    desc = resolve_type_descriptor(annotation, OptionInfo())
    original = getattr(core.build_runtime_param, "original", core.build_runtime_param)
    slow = original(desc)
    try:
        fast = cli_params.fast_value(annotation, value)
    except cli_params.Decline:
        fast = "declined"

    class P:  # what typer's conversion reads of its parameter
        multiple, nargs, name, human_readable_name = False, 1, "x", "X"

        def get_error_hint(self, ctx):
            return "X"

    try:
        want = slow._coerce_value(value, param=P(), ctx=None)
    except Exception as exc:  # noqa: BLE001 - the error is the answer compared
        want = f"error: {exc}"
    return fast, want


@pytest.mark.parametrize("annotation", [float, int, str, Path])
def test_plain_values_convert_as_typers_pydantic_adapter_does(annotation):
    compared = 0
    for value in VALUES + PATHS:
        fast, want = _both(annotation, value)
        if fast == "declined":
            continue
        assert type(fast) is type(want) and (fast == want or fast != fast and want != want), \
            (annotation, value, fast, want)
        compared += 1
    assert compared >= 5


def test_values_pydantic_rejects_are_all_declined():
    """Every value pydantic refuses is left to it (so the user sees typer's own message)."""
    for annotation in (float, int, Path):
        for value in VALUES + PATHS:
            fast, want = _both(annotation, value)
            if isinstance(want, str) and want.startswith("error:"):
                assert fast == "declined", (annotation, value, want)


def test_lists_and_bools_convert_item_by_item():
    assert cli_params.fast_value(List[Path], ["a.ply", "b.ply"]) == [Path("a.ply"), Path("b.ply")]
    assert cli_params.fast_value(list[int], ("1", "2")) == [1, 2]
    assert cli_params.fast_value(bool, False) is False
    with pytest.raises(cli_params.Decline):
        cli_params.fast_value(List[int], ["1", "x"])
    with pytest.raises(cli_params.Decline):
        cli_params.fast_value(bool, "yes")


def _app():
    app = typer.Typer()

    @app.command()
    def run(x: float = typer.Option(0.0), n: int = typer.Option(1),
            p: List[Path] = typer.Argument(...)):
        print(repr((x, n, p)))

    return app


def test_a_command_gives_the_same_answers_and_errors_as_without_the_fast_path(monkeypatch):
    import typer.core as core

    assert cli_params.install()
    fast_build = core.build_runtime_param
    runner = CliRunner()
    cases = [["--x", "0.25", "--n", "3", "a.ply", "b.ply"], ["--x", "abc", "a.ply"],
             ["--n", "1.5", "a.ply"], ["--x", "1_0", "a.ply"], ["--x", "inf", "a.ply"]]
    got = [runner.invoke(_app(), c) for c in cases]
    monkeypatch.setattr(core, "build_runtime_param", fast_build.original)
    want = [runner.invoke(_app(), c) for c in cases]
    for c, g, w in zip(cases, got, want):
        assert (g.exit_code, g.output) == (w.exit_code, w.output), c
    assert got[0].output.strip() == repr((0.25, 3, [Path("a.ply"), Path("b.ply")]))
    assert got[1].exit_code == 2 and "Invalid value" in got[1].output


def test_info_of_a_cached_file_imports_neither_pydantic_nor_numpy(example_step):
    """``shapeverify info`` of a STEP file whose summary is cached parses its options without
    pydantic and writes its table without numpy (together 0.2-0.3 s of CPU per command)."""
    env = {**os.environ, "COLUMNS": "120"}
    first = subprocess.run([sys.executable, "-m", "shapeverify", "info", str(example_step)],
                           capture_output=True, text=True, env=env, timeout=600)
    assert first.returncode == 0, first.stderr[-2000:]
    code = ("import sys; from shapeverify.cli_start import main\n"
            "sys.argv = ['shapeverify', 'info', sys.argv[1]]\n"
            "try:\n    main()\nexcept SystemExit as e:\n    code = e.code\n"
            "print('IMPORTED', 'pydantic' in sys.modules, 'numpy' in sys.modules, code)")
    again = subprocess.run([sys.executable, "-c", code, str(example_step)], capture_output=True,
                           text=True, env=env, timeout=600)
    table, _, flags = again.stdout.rpartition("IMPORTED")
    assert flags.split() == ["False", "False", "0"], again.stdout + again.stderr[-2000:]
    assert table.strip() == first.stdout.strip()    # the same table, bounding box included
    assert "[mm]" in table and "300." in table


def test_info_bounding_box_is_written_as_numpy_writes_it_without_numpy():
    """``info``'s bounding box: ``cli_text.coordinates`` equals ``np.array2string(np.round(v,
    2) + 0.0, precision=2, suppress_small=True)`` -- the text it replaced -- on many vectors."""
    import numpy as np

    from shapeverify.cli_text import coordinates

    rng = np.random.default_rng(32)
    cases = [(0.0, 0.0, -3.0), (300.0, 200.0, 16.03), (-0.001, 0.004, -0.005),
             (0.005, 0.015, 0.025), (1e-9, -1e-9, 0.0), (99999999.99, 1.0, 2.0),
             (1e8, 0.0, 1.0), (float("nan"), 1.0, 2.0), (float("inf"), -1.0, 0.5),
             (-12.345, 0.125, 7.0), (1.005, 2.675, -0.135)]
    for scale in (1e-3, 1e-1, 1.0, 1e2, 1e4, 1e6, 1e7):
        cases += [tuple(rng.normal(0, scale, 3)) for _ in range(60)]
        cases += [tuple(np.round(rng.normal(0, scale, 3), 2)) for _ in range(20)]
    for v in cases:
        want = np.array2string(np.round(np.asarray(v), 2) + 0.0, precision=2,
                               suppress_small=True)
        assert coordinates(v) == want, v
        assert coordinates(list(v)) == want, v
