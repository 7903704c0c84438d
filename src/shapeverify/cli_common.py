"""What the command line's modules share (``cli.py``, ``cli_frontends.py``, ``cli_optics.py``,
``cli_plan.py``): the consoles, the exit codes, the stage lines, the one-line errors, the input
checks and the inspection options ``inspect`` and ``batch`` both offer.

A leaf: it imports no other command-line module (they import it), so no import cycle runs
through ``cli.py``.
"""

from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape

from shapeverify.cli_errors import clean, cli_hint, os_error_message

__all__ = ["console", "out", "EXIT_PASS", "EXIT_FAIL", "EXIT_ERROR", "EXIT_INCOMPLETE",
           "VERBOSE_KEY", "stage", "fail", "internal_error", "guard", "require_extra",
           "require_files", "is_init_mode", "EVALUATION_DISTANCE", "LOWER", "UPPER", "FACES",
           "MIN_COVERAGE", "INIT", "SCAN_UNIT", "PLAN", "MAX_DISTANCE", "renamed"]

from shapeverify.verdict_table import VERDICT_TABLE  # a leaf (no numpy): the exit codes

console = Console(stderr=True)
out = Console()

EXIT_PASS, EXIT_FAIL, EXIT_ERROR, EXIT_INCOMPLETE = (VERDICT_TABLE[v].exit_code for v in
                                                     ("pass", "fail", "error", "incomplete"))
# one option, one default (shapeverify.inspection.default_evaluation_distance), for inspect and batch
EVALUATION_DISTANCE = typer.Option(
    None, "--evaluation-distance",
    help="Scan points farther than this from the CAD are not evaluated [mm] "
         "(default: max(5 x the tolerance, min(1 mm, 5 % of the model size)))")
#: ``--max-distance``: the old name of ``--evaluation-distance`` (inspect, batch) and of
#: ``--reach`` (prepare); still accepted, with a note (:func:`renamed`)
MAX_DISTANCE = typer.Option(None, "--max-distance", hidden=True,
                            help="Old name of --evaluation-distance (inspect, batch) and --reach (prepare)")
# the inspection options that inspect and batch share (one help text each)
LOWER = typer.Option(None, help="Lower limit [mm] (negative: into the material)")
UPPER = typer.Option(None, help="Upper limit [mm]")
FACES = typer.Option(None, "--faces", help="Inspect only these CAD faces, e.g. '0,3,7', or 'seen': the faces the scan saw (default: all)")
MIN_COVERAGE = typer.Option(None, "--min-coverage", help="Least share of the inspected CAD area that must be seen (0..1, default 0.2 = shapeverify.inspection.MIN_COVERAGE); below it the verdict is 'incomplete'")
INIT = typer.Option(None, "--init", help="Start pose T_model_scan: a 4x4 in T.json or T.npy, or a strategy: auto (default: the identity when the scan overlaps the model, else a global search), identity, principal-axes, global")
SCAN_UNIT = typer.Option(None, "--scan-unit", help="Unit of the scan file (mm, cm, m, in, um; default mm)")
PLAN = typer.Option(None, "--plan", help="Inspection plan (plan.yaml): alignment, characteristics with uncertainty; without --tolerance the colour map uses half its first surface profile's zone")
_COMPILE_NOTICES: dict | None = None


def _say_compiling(text: str) -> None:
    console.print(f"[yellow]note:[/yellow] {escape(text)}", soft_wrap=True)


def _watch_compiles() -> None:
    """From the first stage on, say once (with an estimate) when numba compiles a kernel: the
    first run after installing can take a minute, and it must not look like a hang."""
    global _COMPILE_NOTICES
    if _COMPILE_NOTICES is not None:
        return
    from shapeverify.warmup import install_compile_notices

    command = next((a for a in sys.argv[1:] if not a.startswith("-")), "inspect")
    _COMPILE_NOTICES = install_compile_notices(_say_compiling, command)


@contextlib.contextmanager
def stage(name: str, watch: bool = True):
    """Show a spinner while a stage runs, then a tick with its duration.

    ``watch=False``: do not install the compile notices (they import numba, ~1.3 s), for a
    stage that runs no numba kernel in this process (``info`` of a CAD file or mesh)."""
    if watch:
        _watch_compiles()
    t0 = time.perf_counter()
    name = escape(clean(name))  # a non-UTF-8 file name must not stop the command
    with console.status(f"[bold]{name}…"):
        yield
    console.print(f"[green]✓[/green] {name} [dim]({time.perf_counter() - t0:.2f} s)[/dim]")


def fail(message: str) -> None:
    """Print ``error: MESSAGE`` on one line (no markup, no wrapping) and exit with code 2."""
    console.print(f"[bold red]error:[/bold red] {escape(' '.join(clean(message).split()))}",
                  soft_wrap=True)
    raise typer.Exit(EXIT_ERROR)


def internal_error(exc: BaseException, verbose: bool) -> None:
    """An exception that is not one of shapeverify's errors: a bug.  One line and exit code 2;
    the traceback with ``--verbose``."""
    if verbose:
        console.print_exception()
    what = escape(" ".join(clean(f"{type(exc).__name__}: {exc}").split()))
    hint = "the traceback is above" if verbose else "run with --verbose for the traceback"
    console.print(f"[bold red]internal error:[/bold red] {what} (a bug in shapeverify, please "
                  f"report it); {hint}", soft_wrap=True)
    raise typer.Exit(EXIT_ERROR)


VERBOSE_KEY = "shapeverify.verbose"


def guard(fn, *args, _scan_unit=None, **kwargs):
    """Run ``fn``; turn shapeverify's errors (and unreadable or missing files) into a one-line
    message and exit code 2.  Anything else is a bug and propagates to the command group, which
    reports it as an internal error (also exit code 2).  ``_scan_unit``: the ``--scan-unit``
    given, for the command-line hint of a unit mismatch (:func:`cli_errors.cli_hint`)."""
    from shapeverify.errors import is_input_error

    try:
        return fn(*args, **kwargs)
    except OSError as exc:      # a missing input, an output folder that is not there, no room
        fail(os_error_message(exc))
    except Exception as exc:  # noqa: BLE001 - sorted: input errors here, bugs further up
        if not is_input_error(exc):
            raise
        fail(str(exc) + cli_hint(str(exc), _scan_unit))


def require_extra(module: str, extra: str, command: str) -> None:
    """Fail with the install command when an optional front end's dependency is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        fail(f"`shapeverify {command}` needs the '{extra}' extra ({module} is not installed): "
              f"pip install 'shapeverify[{extra}]'")


def require_files(*paths: Path) -> None:
    """Fail fast, before any slow work, when an input file does not exist."""
    for p in paths:
        if not p.exists():
            fail(f"{p}: no such file")
        if p.is_dir():
            fail(f"{p}: is a directory; give a file")
        if not p.is_file():     # a pipe or device: reading it would wait (info hashed a FIFO for ever)
            fail(f"{p}: is not a regular file (a pipe, socket or device); give a file")


def is_init_mode(init: str) -> bool:
    """Whether ``--init`` names a start strategy (else it is a T.json / T.npy file)."""
    from shapeverify.options import is_pose_file

    return not is_pose_file(init)


def renamed(old_value, new_value, old: str, new: str):
    """The value of an option given by its old name ``old`` (a note says so once) or its new
    name ``new``; both given: an error."""
    if old_value is None:
        return new_value
    if new_value is not None:
        fail(f"give {new} only ({old} is its old name)")
    console.print(f"[yellow]note:[/yellow] {old} is now called {new} (the old name will go)",
                  soft_wrap=True)
    return old_value
