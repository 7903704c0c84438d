"""What the command line does before it parses its arguments: start the CAD importer early.

``shapeverify info`` of a CAD file not read before waits for the importer process (a Python that
imports OpenCASCADE, about 1.2 s); importing typer and rich and parsing the command line takes
~0.2 s, so the importer is started before that: :func:`main` (the ``shapeverify`` command and
``python -m shapeverify``) calls :func:`early_importer` before it imports the command line
(``cli._GuardedGroup.main`` calls it too, for ``python -m shapeverify.cli`` and tests; a second
call finds the importer running).  Before that, :func:`main` hands the command to the resident
worker when one runs (``shapeverify worker start``, :mod:`shapeverify.cli_worker`).  Nothing
here imports numpy, OCP or numba.
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["CAD_SUFFIXES", "early_importer", "is_prepared", "main"]

CAD_SUFFIXES = (".step", ".stp", ".igs", ".iges")


def main() -> int | None:
    """The ``shapeverify`` command: hand it to the resident worker if one of this installation
    and version runs (:mod:`shapeverify.cli_worker`, standard library only up to here); else
    start the importer if the command will need it, then run the command line in this process
    (exit codes in :mod:`shapeverify.cli`)."""
    from shapeverify.cli_worker import try_worker

    code = try_worker(sys.argv[1:])
    if code is not None:
        return code
    early_importer(sys.argv[1:])
    from shapeverify.cli import main as run

    return run()


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
