"""What ``shapeverify info`` prints about a model, and a cache of it keyed by the file's content.

Reading a STEP file costs about 1 s of OpenCASCADE import in the importer process before the
first answer (``benchmarks/results_coldstart.md``), however small the file; :func:`read_summary`
answers from OpenCASCADE alone, without numba and without building the model's trimming loops
(:mod:`shapeverify.cad.occ_summary`).  :func:`cached_summary` keeps the :class:`ModelSummary` of each model file it read in
the user's cache directory, under the SHA-256 of the file's bytes, so that ``info`` of the same
file again needs neither OpenCASCADE nor numba.

The cache is safe to lose or damage: an entry is used only when its file content hash, its
format version and the stamp of the reading code (size and modification time of every module
of :mod:`shapeverify.cad` and :mod:`shapeverify.io`, and the package version) all match; a
corrupt or unreadable entry is ignored (and replaced); writing it is best effort (a read-only
cache directory only costs the speed-up).  Directory: ``$SHAPEVERIFY_CACHE_DIR``, else
``$XDG_CACHE_HOME/shapeverify``, else ``~/.cache/shapeverify``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

__all__ = ["ModelSummary", "summarize", "read_summary", "cached_summary", "cache_dir"]

logger = logging.getLogger(__name__)

_FORMAT = 3  # bump when ModelSummary's fields change
_MAX_ENTRIES = 256  # the oldest entries beyond this are removed when one is written


@dataclass(frozen=True)
class ModelSummary:
    """The figures ``shapeverify info`` shows.

    Attributes
    ----------
    kind : str
        "cad", "mesh" or "points".
    faces : int
        CAD faces held (0 for a mesh or a point cloud).
    rational_faces, faces_with_holes : int
        Faces whose surface is rational; faces with more than one trimming loop (0 unless CAD).
    vertices : int or None
        Mesh vertices or cloud points (None for CAD).
    unit : str
        The unit the file declares; ``scale_to_mm`` converts it to mm.
    scale_to_mm : float
    lo, hi : tuple of 3 float
        Axis-aligned bounding box [mm] (:attr:`shapeverify.cad.model.Model.bounds`).
    size : float
        Its diagonal [mm].
    faces_in_file : int or None
        The faces the CAD file declares (None: not known, or not CAD); more than ``faces``
        when some are missing (issue 33 row 2).
    missing : tuple of str
        One line per face of the file that is not in the model, saying which and why.
    supplemental : tuple of int
        The supplemental faces (:attr:`~shapeverify.cad.model.Model.supplemental`: outside
        the part's solid; numbered, but not inspected); the bounds are those of the others.
    """

    kind: str
    faces: int
    rational_faces: int
    faces_with_holes: int
    vertices: int | None
    unit: str
    scale_to_mm: float
    lo: tuple
    hi: tuple
    size: float
    faces_in_file: int | None = None
    missing: tuple = ()
    supplemental: tuple = ()


def face_ranges(idx) -> str:
    """'264-281, 300' for ascending face numbers."""
    out, start = [], None
    for k, i in enumerate(idx):
        if start is None:
            start = i
        if k + 1 == len(idx) or idx[k + 1] != i + 1:
            out.append(f"{start}" if start == i else f"{start}-{i}")
            start = None
    return ", ".join(out)


def summarize(model) -> ModelSummary:
    """The :class:`ModelSummary` of a :class:`~shapeverify.cad.model.Model`."""
    lo, hi = model.bounds
    cad = model.kind == "cad"
    return ModelSummary(
        kind=str(model.kind.value), faces=len(model.faces),
        rational_faces=sum(1 for f in model.faces if f.surface.rational) if cad else 0,
        faces_with_holes=sum(1 for f in model.faces if len(f.loops) > 1) if cad else 0,
        vertices=None if model.vertices is None else int(len(model.vertices)),
        unit=model.unit, scale_to_mm=float(model.scale_to_mm),
        lo=tuple(float(x) for x in lo), hi=tuple(float(x) for x in hi), size=float(model.size),
        faces_in_file=model.n_faces_in_file if cad else None,
        missing=tuple(model.skipped_faces) if cad else (),
        supplemental=tuple(getattr(model, "supplemental", ())) if cad else ())


def read_summary(path) -> ModelSummary:
    """The :class:`ModelSummary` of a model file, read afresh.

    A STEP or IGES file is summarised by OpenCASCADE alone in the importer process
    (:func:`shapeverify.cad.occ_summary.read_summary`: the model's figures, its bounds to about
    1e-6 of its size, with neither numba nor the model's trimming loops); any other file is
    loaded (:func:`shapeverify.cad.load.load_model`) and summarised.

    Raises
    ------
    As :func:`shapeverify.cad.load.load_model`.
    """
    from .load import MODEL_EXTENSIONS, load_model

    path = Path(path)
    ext = path.suffix.lower()
    if ext in (".step", ".stp", ".igs", ".iges") and path.is_file():
        from .occ_worker import summary_isolated

        return summary_isolated(path)
    if ext not in MODEL_EXTENSIONS or not path.is_file():
        load_model(path)  # raises the loader's error for a missing or unsupported file
    return summarize(load_model(path))


def in_unit(summary: ModelSummary, unit: str | None, source: str = "the CAD file") -> ModelSummary:
    """``summary`` of a mesh or point cloud whose coordinates are really in ``unit`` (the
    ``--model-unit`` of ``info``, as :func:`shapeverify.units.scale_model` applies it when
    preparing), or of a CAD file as if it declared ``unit`` instead of its own (with a warning:
    :func:`shapeverify.cad.rescale.summary_with_declared_unit`); ``None``: unchanged.

    Raises
    ------
    ValueError
        An unknown unit; a CAD file whose declared unit has no known size.
    """
    from dataclasses import replace

    from shapeverify.unit_table import unit_factor

    if unit is None:
        return summary
    f = unit_factor(unit)
    if summary.kind == "cad":
        from .rescale import summary_with_declared_unit
        return summary_with_declared_unit(summary, unit, source)
    if f == 1.0:
        return summary
    return replace(summary, unit=str(unit), scale_to_mm=summary.scale_to_mm * f,
                   lo=tuple(x * f for x in summary.lo), hi=tuple(x * f for x in summary.hi),
                   size=summary.size * f)


def cache_dir() -> Path:
    """Where :func:`cached_summary` keeps its entries (see the module docstring)."""
    d = os.environ.get("SHAPEVERIFY_CACHE_DIR")
    if d:
        return Path(d)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "shapeverify"


def _code_stamp() -> str:
    """Changes whenever a module of shapeverify.cad (the importer and the model) or of
    shapeverify.io (the mesh and point-cloud readers) changes."""
    from shapeverify import __version__

    here = Path(__file__).resolve().parent
    h = hashlib.sha256(f"{__version__}/{_FORMAT}".encode())
    for p in sorted(here.glob("*.py")) + sorted((here.parent / "io").glob("*.py")):
        st = p.stat()
        h.update(f"{p.name}:{st.st_size}:{st.st_mtime_ns};".encode())
    return h.hexdigest()[:16]


def _file_hash(path: Path) -> str:
    """The file's SHA-256 (hex; remembered for an unchanged file where
    :mod:`shapeverify._file_memo` is enabled)."""
    from shapeverify._file_memo import FILE_HASHES

    return FILE_HASHES.call(_sha256, path)


def _sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _read_entry(entry: Path, stamp: str) -> ModelSummary | None:
    try:
        data = json.loads(entry.read_text())
        if data.pop("stamp") != stamp:
            return None
        data["lo"], data["hi"] = tuple(map(float, data["lo"])), tuple(map(float, data["hi"]))
        data["missing"] = tuple(str(x) for x in data.get("missing", ()))
        data["supplemental"] = tuple(int(x) for x in data.get("supplemental", ()))
        s = ModelSummary(**data)
        if not (len(s.lo) == len(s.hi) == 3 and isinstance(s.faces, int)):
            raise ValueError("malformed entry")
        return s
    except FileNotFoundError:
        return None
    except Exception as exc:  # noqa: BLE001 - a damaged entry is only a missed speed-up
        logger.debug("ignoring the damaged cache entry %s: %s", entry, exc)
        return None


def _write_entry(entry: Path, summary: ModelSummary, stamp: str) -> None:
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=entry.parent, prefix=".tmp-", suffix=".json")
        with os.fdopen(fd, "w") as f:
            json.dump({**asdict(summary), "stamp": stamp}, f)
        os.replace(tmp, entry)
        old = sorted(entry.parent.glob("info-*.json"), key=lambda p: p.stat().st_mtime)
        for p in old[:-_MAX_ENTRIES]:
            p.unlink(missing_ok=True)
    except OSError as exc:
        logger.debug("could not write the cache entry %s: %s", entry, exc)


def is_cached(path) -> bool:
    """Whether :func:`cached_summary` would answer ``path`` from the cache (hashes the file)."""
    try:
        path = Path(path)
        entry = cache_dir() / f"info-{_file_hash(path)}{path.suffix.lower()}.json"
        return _read_entry(entry, _code_stamp()) is not None
    except OSError:
        return False


def cached_summary(path, load) -> tuple[ModelSummary, bool]:
    """The :class:`ModelSummary` of the model file ``path``, from the cache when it holds one.

    Parameters
    ----------
    path : str or os.PathLike
        A model file (its bytes are hashed: SHA-256, about 1 GB/s).
    load : callable(path) -> Model or ModelSummary
        Reads the file on a cache miss (:func:`read_summary`, or
        ``shapeverify.cad.load.load_model``); its exceptions propagate and nothing is cached.

    Returns
    -------
    (ModelSummary, bool)
        The summary, and whether it came from the cache.
    """
    path = Path(path)
    stamp = _code_stamp()
    entry = cache_dir() / f"info-{_file_hash(path)}{path.suffix.lower()}.json"
    hit = _read_entry(entry, stamp)
    if hit is not None:
        logger.info("%s: summary from the cache (%s)", path, entry)
        if hit.missing:
            logger.warning("%s: %d of the %s faces in the file are not in the model: %s", path,
                           len(hit.missing), hit.faces_in_file, "; ".join(hit.missing))
        return hit, True
    got = load(path)
    summary = got if isinstance(got, ModelSummary) else summarize(got)
    _write_entry(entry, summary, stamp)
    return summary, False
