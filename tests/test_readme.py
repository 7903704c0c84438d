"""The README's examples work as written.

* Every ``python`` block runs, in order and in one namespace (as a reader would paste them), in
  a temporary folder holding the files the README names: ``part.step`` (the bundled example
  panel), ``scan.ply`` (a simulated scan of it with a 0.4 mm dent) and ``plan.yaml`` (the
  README's own YAML plan).  Their answers are checked against the simulator's truth.
* Every ``shapeverify ...`` line of the ``sh`` blocks parses with the command line's own parser
  (options, arities, choices), without running; the ``make`` targets exist in the Makefile.
"""

from __future__ import annotations

import contextlib
import io
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


@pytest.fixture(scope="module")
def readme_folder(tmp_path_factory):
    """part.step (the example panel), scan.ply (a simulated scan, 0.4 mm dent), plan.yaml."""
    import shapeverify as sv
    from shapeverify.cad.examples import example_part_step
    from shapeverify.io.points import write_ply
    from shapeverify.simulate import DENT, virtual_scan

    d = tmp_path_factory.mktemp("readme")
    step = example_part_step(d / "part.step")
    sim = virtual_scan(sv.load_model(step), pixel=1.5, noise=0.02, outlier_fraction=0.02,
                       dents=[(0.4, 15.0)], motion=(3.0, 5.0), rng=7)
    write_ply(d / "scan.ply", sim.scan)
    plans = [b for b in blocks("yaml") if "characteristics:" in b]
    assert len(plans) == 1
    (d / "plan.yaml").write_text(plans[0])
    dent = sim.points[sim.labels == DENT].mean(axis=0)
    return d, dent


@pytest.mark.slow
def test_readme_python_blocks_run_and_answer(readme_folder, monkeypatch):
    folder, dent = readme_folder
    monkeypatch.chdir(folder)
    code = blocks("python")
    assert len(code) == 3, "the README has three Python examples: library, side modules, plans"
    ns: dict = {}
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code[0], "README.md:python[0]", "exec"), ns)
    # the library example: the 0.4 mm dent fails the 0.2 mm tolerance, and is found where it is
    res = ns["res"]
    assert res.verdict == "fail" and res.rule == "regions"
    assert np.linalg.norm(res.regions[0].centroid - dent) < 15.0
    assert (folder / "part.svm").is_file()
    assert "fail" in printed.getvalue()

    with contextlib.redirect_stdout(printed):
        exec(compile(code[1], "README.md:python[1]", "exec"), ns)
    # side modules: the fits recover the shapes they were given, the views see the part
    assert ns["sph"].radius == pytest.approx(5.0, abs=1e-6)
    assert np.allclose(ns["sph"].center, [10.0, 20.0, 30.0], atol=1e-6)
    assert ns["cyl"].radius == pytest.approx(8.0, abs=1e-6)
    assert abs(abs(ns["cyl"].axis[2]) - 1.0) < 1e-9
    assert ns["fit"].rms < 0.05                      # a 12 x 12 patch follows the panel
    assert ns["hits"].hit.mean() > 0.2 and ns["images"]["mask"].any()
    assert np.abs(ns["res"].T_model_scan - np.eye(4)).max() < 1e-3   # the pose it started at

    with contextlib.redirect_stdout(printed):
        exec(compile(code[2], "README.md:python[2]", "exec"), ns)
    # the plan on the bundled panel: the hole is in tolerance, the dented skin is not
    plan_res = ns["res"]
    verdicts = {c.name: c.verdict for c in plan_res.characteristics}
    assert verdicts["SKIN"] == "fail" and verdicts["H1"] == "pass", verdicts
    assert (folder / "panel.pdf").stat().st_size > 10_000
