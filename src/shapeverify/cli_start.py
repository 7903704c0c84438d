"""What the command line does before it parses its arguments: start the CAD importer early.

``shapeverify info`` of a CAD file not read before waits for the importer process (a Python that
imports OpenCASCADE, about 1.2 s); importing typer and rich and parsing the command line takes
~0.2 s, so the importer is started before that: :func:`main` (the ``shapeverify`` command and
``python -m shapeverify``) calls :func:`early_importer` before it imports the command line
(``cli._GuardedGroup.main`` calls it too, for ``python -m shapeverify.cli`` and tests; a second
call finds the importer running).  Before that, :func:`main` hands the command to the resident
worker when one runs (``shapeverify worker start``, :mod:`shapeverify.cli_worker`).  Nothing
here imports numpy, OCP or numba, except :func:`preimport` for an ``inspect`` that runs in
this process (the modules it would import anyway, with the garbage collector paused);
:func:`run` ends the process without the interpreter's teardown.
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["CAD_SUFFIXES", "early_importer", "is_prepared", "main", "run"]

CAD_SUFFIXES = (".step", ".stp", ".igs", ".iges")


def main() -> int | None:
    """The ``shapeverify`` command: hand it to the resident worker if one of this installation
    and version runs (:mod:`shapeverify.cli_worker`, standard library only up to here); else
    start the importer if the command will need it, then run the command line in this process
    (exit codes in :mod:`shapeverify.cli`)."""
    from shapeverify.cli_worker import _command, runs_kernels, try_worker

    code = try_worker(sys.argv[1:])
    if code is not None:
        return code
    early_importer(sys.argv[1:])
    if runs_kernels(sys.argv[1:]) and _command(sys.argv[1:]) == "inspect":
        preimport()
    from shapeverify.cli import main as run

    return run()


def run() -> None:
    """The ``shapeverify`` console command and ``python -m shapeverify``: :func:`main`, then
    the process ends as the interpreter would end it (non-daemon threads joined, ``atexit``
    handlers run, stdout and stderr flushed, the same exit status) but without tearing down
    every module and object one by one: after numpy, scipy and numba that teardown cost
    ~0.3 s of CPU, 10-15 % of a plain ``inspect`` (issue 32 item 7).  An exception other
    than ``SystemExit`` ends the process as before (traceback, status 1)."""
    try:
        code = main()
    except SystemExit as exc:
        code = exc.code
    end(code)


def end(code) -> None:
    """End the process with ``sys.exit(code)``'s status, skipping the interpreter's teardown
    (see :func:`run`); falls back to ``sys.exit`` when a step of the orderly part fails."""
    import os

    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:
        sys.exit(code)          # the interpreter prints it and exits 1, as before
    try:
        threading = sys.modules.get("threading")
        if threading is not None:
            threading._shutdown()   # what Py_Finalize does first: join non-daemon threads
        import atexit

        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except BaseException:       # noqa: BLE001 - e.g. a closed pipe: end as the interpreter does
        sys.exit(status)
    os._exit(status & 0xFF)


#: what ``inspect`` imports before its work (the resident worker's preload imports the same)
INSPECT_MODULES = ("shapeverify.cli", "shapeverify.cli_common", "shapeverify.inspection",
                   "shapeverify.nearest", "shapeverify.options", "shapeverify.pipeline",
                   "shapeverify.registration")


def preimport(modules=INSPECT_MODULES) -> None:
    """Import ``modules`` with Python's cyclic garbage collector paused, then freeze what they
    made (``gc.freeze``: later collections do not walk the libraries' objects again).  numpy,
    scipy and numba create some million objects as they import: the collections that set off
    cost ~0.1-0.2 s of CPU and free nearly nothing.  The compile notice of the first run after
    installing (numba compiles ``nearest``'s eager kernel at its import) is installed first.
    An import that fails is left to the command (it imports again and reports it)."""
    import gc
    import importlib

    was = gc.isenabled()
    gc.disable()
    try:
        from shapeverify._lazy import kdtree_class
        from shapeverify._start_shortcuts import (defer_numba_registries,
                                                   import_kernel_env_modules, import_numba)

        import_numba()              # without PyYAML (numba reads a config file with it)
        defer_numba_registries()    # cached kernels load without numba's registries (~0.2 s)
        kdtree_class()              # scipy's k-d tree without scipy.spatial (0.1-0.2 s)
        import_kernel_env_modules()  # what the kernels' environments name
        for name in modules:
            importlib.import_module(name)
            if name == "shapeverify.cli_common":
                importlib.import_module(name)._watch_compiles()
    except Exception:   # noqa: BLE001 - the command imports it again and says what failed
        pass
    finally:
        gc.freeze()
        if was:
            gc.enable()


def early_importer(argv: list) -> None:
    """For ``info`` of a CAD file whose summary is not cached, start the importer before the
    command line is parsed (typer takes ~0.2 s for that, which the importer's own start, ~1 s,
    then overlaps).  A wrong guess costs only an idle importer, killed at exit."""
    try:
        i = argv.index("info")
    except ValueError:
        return
    if not all(str(a).startswith("-") for a in argv[:i]):
        return  # "info" is not the command here
    rest, skip, model = [str(a) for a in argv[i + 1:]], False, None
    for tok in rest:
        if skip:
            skip = False
        elif tok in ("--json", "--model-unit"):
            skip = True
        elif not tok.startswith("-"):
            model = Path(tok)
            break
    if model is None or model.suffix.lower() not in CAD_SUFFIXES or not model.is_file():
        return
    features = "--features" in rest
    if not features:
        from shapeverify.cad.summary import is_cached

        if is_cached(model):
            return
    from shapeverify.cad.occ_worker import prestart

    prestart(summary=not features)


def is_prepared(model: Path) -> bool:
    """Whether ``model`` is a prepared model (.svm); for a CAD file told without importing the
    pipeline (numpy), which would delay the start of the importer."""
    if model.suffix.lower() in CAD_SUFFIXES:
        return False
    from shapeverify.pipeline import PREPARED_SUFFIX

    return model.suffix.lower() == PREPARED_SUFFIX
