"""The README's examples work as written, on the files the README says how to make.

* The folder is made the README's way: ``python -m shapeverify.demo DIR`` (what ``make demo``
  runs) writes ``panel.step``, ``panel.svm`` and ``scan.ply`` (a simulated scan with a 0.4 mm
  dent, whose true place the demo prints); ``plan.yaml`` is the README's own YAML plan, saved
  as the README says.  No other file is put there: a snippet that reads a file nobody made
  fails here as it would for a reader (issue 32).
* Every ``python`` block runs as it is, in order and in one namespace (as a reader would paste
  them); the ``run_batch`` block is run as the script the README says it is
  (``python batch_example.py``), which needs its main guard.  Their answers are checked
  against the simulator's truth.
* The ``sh`` lines of "Command line" and "Inspection plans" run as they are (in-process, with the
  command line's own parser), in that folder, with their documented exit codes; every other
  ``shapeverify ...`` line parses with the command line's parser (options, arities, choices)
  without running (a server, a cluster, camera images); the ``make`` targets exist.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
_BLOCK = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```", re.S | re.M)


def blocks(lang: str) -> list[str]:
    """The README's fenced code blocks of one language, in order."""
    return [body for kind, body in _BLOCK.findall(README.read_text()) if kind == lang]


def shell_commands(text: str) -> list[str]:
    """Logical command lines of a shell block: continuations joined, comments dropped."""
    lines, cur = [], ""
    for raw in text.splitlines():
        line = raw.split(" #")[0].rstrip() if not raw.lstrip().startswith("#") else ""
        if line.endswith("\\"):
            cur += line[:-1] + " "
            continue
        cur += line
        if cur.strip():
            lines.append(cur.strip())
        cur = ""
    return lines


def parse_cli(line: str) -> None:
    """Parse ``shapeverify ARGS`` with the CLI's parser (raises click's UsageError on a mistake)."""
    import click
    import typer

    from shapeverify.cli import app

    # "[--model part.svm --pose pose.json]" in the README marks optional options: check them too
    args = shlex.split(line.replace("[", " ").replace("]", " "))
    assert args[0] == "shapeverify", line
    group = typer.main.get_command(app)
    ctx = click.Context(group, info_name="shapeverify")
    sub = group.get_command(ctx, args[1])
    if sub is None:
        raise click.UsageError(f"no such command {args[1]!r}")
    with sub.make_context(args[1], args[2:], parent=ctx):
        pass


def test_readme_shell_lines_parse_with_the_cli():
    cmds = [c for b in blocks("sh") for c in shell_commands(b)]
    cli = [c for c in cmds if c.startswith("shapeverify ")]
    assert len(cli) >= 15, cli  # the README's command examples are found
    bad = []
    for c in cli:
        try:
            parse_cli(c)
        except Exception as exc:  # noqa: BLE001 - collected, all reported at once
            bad.append(f"{c}\n    -> {type(exc).__name__}: {exc}")
    assert not bad, "README command lines the CLI rejects:\n" + "\n".join(bad)


def test_the_shell_line_check_catches_a_wrong_arity():
    # (typer may bring its own copy of click, so the exception class is not imported here)
    with pytest.raises(Exception, match="unexpected extra argument"):
        parse_cli("shapeverify fit points.xyz --surface --ctrl 12 12 -o patch.step")
    parse_cli("shapeverify fit points.xyz --surface --ctrl 12 --ctrl 12 -o patch.step")


def test_readme_make_targets_exist():
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M))
    used = {c.split()[1] for b in blocks("sh") for c in shell_commands(b) if c.startswith("make ")}
    assert used and used <= targets, used - targets


def section(title: str) -> str:
    """The README's text under ``## title`` (to the next ``## ``)."""
    text = README.read_text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


@pytest.fixture(scope="module")
def readme_folder(tmp_path_factory):
    """The folder of "Files for the examples": what ``make demo`` writes, plus plan.yaml."""
    import os
    import subprocess
    import sys

    d = tmp_path_factory.mktemp("readme") / "demo-output"
    make_demo = re.search(r"^demo:.*\n\t(.*)$", (ROOT / "Makefile").read_text(), re.M).group(1)
    assert "-m shapeverify.demo demo-output" in make_demo, make_demo
    proc = subprocess.run([sys.executable, "-m", "shapeverify.demo", str(d)], capture_output=True,
                          text=True, timeout=900, env={**os.environ, "COLUMNS": "400"})
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for name in ("panel.step", "panel.svm", "scan.ply"):       # what the README says it writes
        assert name in section("Files for the examples") and (d / name).is_file(), name
    dent = re.search(r"0\.4 mm dent at \[([^\]]*)\]", " ".join(proc.stdout.split()))
    plans = [b for b in blocks("yaml") if "characteristics:" in b]
    assert len(plans) == 1 and "save\nit as `plan.yaml`" in README.read_text()
    (d / "plan.yaml").write_text(plans[0])
    return d, np.array(dent.group(1).split(), float)


def _run_cli_line(line: str) -> int:
    from typer.testing import CliRunner

    from shapeverify.cli import app

    res = CliRunner().invoke(app, shlex.split(line)[1:])
    if res.exit_code not in (0, 1) or res.exception and not isinstance(res.exception, SystemExit):
        raise AssertionError(f"{line}\n{res.output[-3000:]}")
    return res.exit_code


@pytest.mark.slow
def test_readme_examples_run_as_written(readme_folder, monkeypatch):
    import subprocess
    import sys

    folder, dent = readme_folder
    monkeypatch.chdir(folder)
    code = blocks("python")
    assert len(code) == 5, "library, side modules, files for the command line, plans, run_batch"
    ns: dict = {}
    printed = io.StringIO()

    def run(i):
        with contextlib.redirect_stdout(printed):
            exec(compile(code[i], f"README.md:python[{i}]", "exec"), ns)

    run(0)
    # the library example: the demo's 0.4 mm dent fails the 0.2 mm tolerance, found where it is
    res = ns["res"]
    assert res.verdict == "fail" and res.rule == "regions"
    assert np.linalg.norm(res.regions[0].centroid - dent) < 15.0
    assert (folder / "panel.svm").is_file()
    assert "fail" in printed.getvalue()

    run(1)
    # side modules: the fits recover the shapes they were given, the views see the part
    assert ns["sph"].radius == pytest.approx(5.0, abs=1e-6)
    assert np.allclose(ns["sph"].center, [10.0, 20.0, 30.0], atol=1e-6)
    assert ns["cyl"].radius == pytest.approx(8.0, abs=1e-6)
    assert abs(abs(ns["cyl"].axis[2]) - 1.0) < 1e-9
    assert ns["fit"].rms < 0.05                      # a 12 x 12 patch follows the panel
    assert ns["hits"].hit.mean() > 0.2 and ns["images"]["mask"].any()
    assert np.abs(ns["res"].T_model_scan - np.eye(4)).max() < 1e-3   # the pose it started at

    run(2)                                           # the files the command lines read
    assert {"phase.npy", "points.xyz", "sphere.xyz"} <= {p.name for p in folder.iterdir()}

    # "Command line": every line runs as it is; inspect fails the dented scan (exit 1)
    cli = [c for c in shell_commands(next(b for b in blocks("sh") if "shapeverify fit" in b))]
    assert len(cli) == 7, cli
    codes = {c.split()[1] + (" " + c.split()[2] if c.split()[1] == "fit" else ""): _run_cli_line(c)
             for c in cli}
    assert codes.pop("inspect") == 1 and set(codes.values()) == {0}, codes
    for out in ("report.html", "summary.png", "deviations.ply", "result.json", "trend.png",
                "unwrapped.npy", "phase.png", "patch.step", "sphere.json"):
        assert (folder / out).stat().st_size > 0, out
    sphere = json.loads((folder / "sphere.json").read_text())
    assert sphere["fit"]["radius"] == pytest.approx(5.0, abs=1e-6)   # 5 mm, read in metres

    run(3)
    # the plan on the bundled panel: the hole is in tolerance, the dented skin is not
    plan_res = ns["res"]
    verdicts = {c.name: c.verdict for c in plan_res.characteristics}
    assert verdicts["SKIN"] == "fail" and verdicts["H1"] == "pass", verdicts
    assert (folder / "panel.pdf").stat().st_size > 10_000
    plan_lines = shell_commands(next(b for b in blocks("sh") if "--plan plan.yaml" in b))
    assert [_run_cli_line(c) for c in plan_lines] == [0, 1, 0], plan_lines
    assert (folder / "r.pdf").stat().st_size > 10_000 and (folder / "h1.csv").is_file()

    # run_batch: the README's script, run the way it says, on the folder its shell line makes
    batch_sh = next(b for b in blocks("sh") if "shapeverify batch" in b)
    subprocess.run(shell_commands(batch_sh)[0], shell=True, check=True)    # mkdir scans, cp
    (folder / "batch_example.py").write_text(code[4])
    proc = subprocess.run([sys.executable, "batch_example.py"], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "1 scans: 0 pass, 1 fail" in proc.stdout
    assert "if __name__ == \"__main__\":" in code[4] and "main guard" in code[4]
