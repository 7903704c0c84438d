"""The command line's front ends: ``serve`` (HTTP, the ``service`` extra) and ``batch`` (a folder
of scans on Dask, the ``batch`` extra).  Both call the one pipeline
(:func:`shapeverify.pipeline.inspect_scan`); see :mod:`shapeverify.cli` for the exit codes.
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from shapeverify.verdict_table import VERDICT_TABLE, most_severe


def register_commands(app: typer.Typer) -> None:
    """Add ``serve`` and ``batch`` to ``app``."""
    from shapeverify import cli_common as _cli

    @app.command()
    def serve(
        models: List[Path] = typer.Argument(..., help="Prepared models (.svm); the file stem is the model name"),
        host: str = typer.Option("127.0.0.1", help="Address to bind (loopback by default)"),
        port: int = typer.Option(8000, help="Port"),
        db: Path = typer.Option(Path("history.sqlite"), "--db", help="SQLite history (WAL mode)"),
        token: Optional[str] = typer.Option(None, "--token", envvar="SHAPEVERIFY_TOKEN",
                                            help="Require 'Authorization: Bearer TOKEN' on every request"),
        max_body_mb: float = typer.Option(64.0, help="Largest accepted scan upload [MB] (413 above)"),
        time_limit: float = typer.Option(60.0, help="Per-request time limit in seconds (504 above; nothing is stored)"),
        threads: int = typer.Option(2, help="Inspections run at once per server process (one per core: the "
                                            "numeric kernels release Python's lock)"),
        workers: int = typer.Option(1, help="Server processes sharing the port (keep-alive connections stay "
                                            "with one process, so few clients may load them unevenly; "
                                            "prefer --threads on one machine)"),
        keep_scans: bool = typer.Option(True, "--keep-scans/--no-keep-scans",
                                        help="Store each scan beside the history (GET /report/{id} needs it)"),
    ):
        """Serve inspections over HTTP with the prepared models kept in memory."""
        _cli.require_extra("fastapi", "service", "serve")
        _cli.require_extra("uvicorn", "service", "serve")
        from shapeverify.service import serve as run_server

        if max_body_mb <= 0 or time_limit <= 0 or threads < 1 or workers < 1:
            _cli.fail("--max-body-mb and --time-limit must be > 0; --threads and --workers >= 1")

        def ready(loaded: dict) -> None:
            _cli.console.print(f"[green]✓[/green] serving {sorted(loaded)} on http://{host}:{port} "
                          f"(history: {db}; {workers} process(es) x {threads} thread(s)); "
                          f"API docs at http://{host}:{port}/docs")

        _cli.console.print(f"loading and warming up {len(models)} prepared model(s)…")
        _cli.guard(run_server, models, host=host, port=port, db_path=db, token=token,
               max_body_bytes=int(max_body_mb * 1024 * 1024), time_limit_s=time_limit, threads=threads,
               workers=workers, keep_scans=keep_scans, on_ready=ready)


    @app.command()
    def batch(
        model: Path = typer.Argument(..., help="Prepared model (.svm)"),
        scans_dir: Path = typer.Argument(..., help="Folder of scans"),
        out_dir: Path = typer.Option(..., "--out", help="Output folder (JSON per scan, summary.csv, dask.log: Dask's own log lines, on the terminal too with shapeverify --verbose batch)"),
        tolerance: Optional[float] = typer.Option(None, help="Symmetric tolerance ±MM"),
        lower: Optional[float] = _cli.LOWER,
        upper: Optional[float] = _cli.UPPER,
        evaluation_distance: Optional[float] = _cli.EVALUATION_DISTANCE,
        faces: Optional[str] = _cli.FACES,
        min_coverage: Optional[float] = _cli.MIN_COVERAGE,
        init: Optional[str] = _cli.INIT,
        scan_unit: Optional[str] = _cli.SCAN_UNIT,
        plan: Optional[Path] = _cli.PLAN,
        part_pattern: Optional[str] = typer.Option(
            None, "--part-pattern", help="The part id in the history is taken from the scan's "
            "file name: the first group (else the whole match) of this regular expression, e.g. "
            "'SN(\\d+)' (default: the file name without its suffix)"),
        scheduler: Optional[str] = typer.Option(None, help="Existing Dask scheduler address (default: local cluster)"),
        workers: int = typer.Option(2, help="Local worker processes"),
        reports: bool = typer.Option(False, "--reports", help="Also write an HTML report per scan"),
        db: Optional[Path] = typer.Option(None, "--db", help="Append every result to this SQLite history"),
        retry_errors: bool = typer.Option(False, "--retry-errors", help="Inspect again the scans that failed before"),
        max_distance: Optional[float] = _cli.MAX_DISTANCE,
    ):
        """Inspect every scan in a folder in parallel on Dask (resumable: done scans are skipped)."""
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

        _cli.require_extra("distributed", "batch", "batch")
        from shapeverify.batch import run_batch
        from shapeverify.options import InspectionOptions

        evaluation_distance = _cli.renamed(max_distance, evaluation_distance, "--max-distance",
                                           "--evaluation-distance")
        init_file = Path(init) if init is not None and not _cli.is_init_mode(init) else None
        _cli.require_files(*([init_file] if init_file is not None else []),
                            *([plan] if plan is not None else []))
        options = _cli.guard(InspectionOptions.from_cli, dict(
            tolerance=tolerance, lower=lower, upper=upper, evaluation_distance=evaluation_distance,
            faces=faces, min_coverage=min_coverage, init=init, scan_unit=scan_unit, plan=plan))

        with Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                      TimeRemainingColumn(), console=_cli.console) as bar:
            task = bar.add_task("inspecting", total=None)

            def tick(done: int, total: int, name: str) -> None:
                bar.update(task, completed=done, total=total, description=name)

            summary = _cli.guard(run_batch, model, scans_dir, out_dir, options,
                                  workers=scheduler or workers, reports=reports,
                                  db_path=db, retry_errors=retry_errors, progress=tick,
                                  part_pattern=part_pattern, _scan_unit=scan_unit)
        s = summary
        _cli.out.print(f"{s.total} scans ({s.skipped} already done): {s.passed} pass, {s.failed} fail, "
                  f"{s.incomplete} incomplete, {s.errors} error; {s.scans_per_minute:.1f} scans/min; "
                  f"summary: {s.summary_csv}; Dask's log: {Path(out_dir) / 'dask.log'}")
        worst = most_severe(v for v, n in s.counts.items() if n)
        raise typer.Exit(_cli.EXIT_PASS if worst is None else VERDICT_TABLE[worst].exit_code)
