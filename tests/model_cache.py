"""An on-disk cache of the CAD models and prepared models the tests read from ``../shared/data``,
so that a part imported (``load_model``: the impeller is 9 s of CPU in the importer) or prepared
in several test modules is built once per suite run and loaded (0.03-0.05 s) by the others,
also across pytest-xdist's worker processes (a file lock per entry: the second worker waits
for the first one's file instead of building it again).

An entry's key is the SHA-256 of the model file's bytes, the arguments, the SHA-256 of every
source file of the imported ``shapeverify`` package and the versions of numpy, scipy, numba
and OCP: a change to the code or the libraries makes a new entry, never a stale answer.  The
cached objects are what :meth:`Model.save` / :meth:`Prepared.save` write and ``load_model`` /
``load_prepared`` read back bitwise (``tests/test_persist.py``).  Directory:
``$SHAPEVERIFY_TEST_CACHE/shapeverify-test-cache/models/<code key>`` (default: the system's
temporary folder); delete it to start afresh.

Besides models and preparations: the semantic PMI a STEP file holds (:func:`cached_pmi`, what
``read_pmi`` returned, pickled) and arrays a test helper computes from a file, e.g.
OpenCASCADE's tessellation of it (:func:`cached_arrays`; the helper's own source files are
part of that key, so an edit of the helper makes a new entry).
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import os
import tempfile
from pathlib import Path

# the library's own functions, bound when this module is first imported: a test may put
# load_model_stand_in / read_pmi_stand_in in their place (e.g. for a command it runs in-process),
# and the entries must still be built by the real ones
from shapeverify.cad.load import load_model as _load_model
from shapeverify.cad.pmi import read_pmi as _read_pmi


#: an entry folder of other code (another checkout, an older commit) unused this long is removed
STALE_S = 2 * 86400


def cache_root() -> Path:
    """The folder of this code version's entries (``models/<code key>``); the folders of other
    code versions not used for :data:`STALE_S` are removed, so the cache does not grow without
    end as the code changes."""
    import shutil
    import time

    base = Path(os.environ.get("SHAPEVERIFY_TEST_CACHE") or tempfile.gettempdir())
    top = base / "shapeverify-test-cache" / "models"
    d = top / code_key()[:20]
    d.mkdir(parents=True, exist_ok=True)
    os.utime(d)
    for other in top.iterdir():
        try:
            if other != d and other.is_dir() and time.time() - other.stat().st_mtime > STALE_S:
                shutil.rmtree(other, ignore_errors=True)
        except OSError:
            pass
    return d


@functools.lru_cache(maxsize=1)
def code_key() -> str:
    """SHA-256 of the shapeverify sources in use and the numeric libraries' versions."""
    import numba
    import numpy
    import scipy

    import shapeverify

    h = hashlib.sha256()
    root = Path(shapeverify.__file__).resolve().parent
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes() + b"\0")
    try:
        from importlib.metadata import version
        ocp = version("cadquery-ocp-novtk")
    except Exception:  # noqa: BLE001 - another OCP distribution: its module file stands in
        import OCP
        ocp = str(getattr(OCP, "__file__", ""))
    h.update(json.dumps([numpy.__version__, scipy.__version__, numba.__version__, ocp]).encode())
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def _file_key(path: str, size: int, mtime_ns: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _entry(path, what: str, args: dict, suffix: str, code=()) -> Path:
    p = Path(path).resolve()
    st = p.stat()
    extra = []
    for f in code:                      # test helpers' source files (cached_arrays)
        f = Path(f).resolve()
        fs = f.stat()
        extra.append(_file_key(str(f), fs.st_size, fs.st_mtime_ns))
    key = hashlib.sha256(json.dumps([what, _file_key(str(p), st.st_size, st.st_mtime_ns),
                                     sorted(args.items()), code_key()] + extra).encode()
                         ).hexdigest()
    return cache_root() / f"{p.stem}-{what}-{key[:24]}{suffix}"


@contextlib.contextmanager
def _locked(entry: Path):
    with open(entry.with_suffix(entry.suffix + ".lock"), "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _cached(entry: Path, build, save, load):
    with _locked(entry):
        if entry.is_file():
            try:
                return load(entry)
            except (ValueError, OSError):       # a damaged entry: built again below
                entry.unlink(missing_ok=True)
        obj = build()
        tmp = entry.with_suffix(f".{os.getpid()}{entry.suffix}")
        save(obj, tmp)
        os.replace(tmp, entry)
        return obj


def _named(model, path):
    """The model as if read from ``path`` (an entry may have been made from an equal file at
    another path, e.g. the example panel written to another temporary folder)."""
    object.__setattr__(model, "source", str(path))
    return model


def _pickled(entry: Path, build):
    """``build()``, pickled at ``entry`` once per code version."""
    import pickle

    def save(obj, p):
        with open(p, "wb") as fh:
            pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)

    def load(p):
        with open(p, "rb") as fh:
            try:
                return pickle.load(fh)
            except (pickle.UnpicklingError, EOFError) as e:
                raise ValueError(f"{p}: damaged entry") from e

    return _cached(entry, build, save, load)


def _with_features(model, entry: Path):
    """``model`` (the model of the cache entry ``entry``) with what
    :func:`shapeverify.characteristics.features.model_features` and ``feature_notes`` return
    for it in place (the attributes model_features caches its answer in), computed once per
    entry: the features fit a plane and a cylinder to every face (NIST CTC 02: 16 s of CPU),
    and every plan from PMI, plan evaluation and feature lookup of a NIST module asked for
    them again -- on the model and again on the prepared model's copy."""
    from shapeverify.characteristics.features import feature_notes, model_features

    def build():
        return tuple(model_features(model)), tuple(feature_notes(model))

    feats, notes = _pickled(entry.with_name(entry.name + ".features.pkl"), build)
    object.__setattr__(model, "_sv_features", feats)
    object.__setattr__(model, "_sv_feature_notes", notes)
    return model


def cached_model(path, *, features: bool = False):
    """``shapeverify.load_model(path)`` of a CAD file, imported once per code version.
    ``features``: with its :func:`model_features` in place, also computed once per code version
    (what model_features would compute on the model and keep on it)."""
    entry = _entry(path, "model", {}, ".svmodel")
    model = _named(_cached(entry, lambda: _load_model(path), lambda m, p: m.save(p),
                           _load_model), path)
    return _with_features(model, entry) if features else model


def cached_prepared(path, *, features: bool = False, **kwargs):
    """``shapeverify.prepare(load_model(path), **kwargs)``, built once per code version.
    ``features``: as in :func:`cached_model`, on ``prep.model``: the model entry's features
    (``prep.model`` is that entry's model, saved and read back bitwise, and its features
    pickle byte for byte the same: NIST CTC 02, FTC 06 and FTC 08 checked), so a part's
    features are computed once per run, not once more per spacing it is prepared at (CTC 02:
    16 s of CPU each).

    ``allow_incomplete=True`` on a complete model is the same preparation as without it
    (prepare only checks completeness with it): such a call shares the entry without it (FTC
    06 and FTC 08 at 1 mm were prepared twice per run, from modules that pass it for every
    file and from modules that pass it only for an incomplete model)."""
    from shapeverify.cad.completeness import is_incomplete
    from shapeverify.nearest import load_prepared, prepare

    if kwargs.get("allow_incomplete") is True and not is_incomplete(cached_model(path)):
        kwargs = {k: v for k, v in kwargs.items() if k != "allow_incomplete"}
    entry = _entry(path, "prepared", kwargs, ".svm")
    prep = _cached(entry, lambda: prepare(cached_model(path), **kwargs),
                   lambda prep, p: prep.save(p), load_prepared)
    _named(prep.model, path)
    if features:
        _with_features(prep.model, _entry(path, "model", {}, ".svmodel"))
    return prep


def cached_pmi(path):
    """``shapeverify.cad.pmi.read_pmi(path)`` of a STEP file, read once per code version (the
    dict pickled as it came back from the importer)."""
    pmi = _pickled(_entry(path, "pmi", {}, ".pkl"), lambda: _read_pmi(path))
    pmi["source"] = str(Path(path))
    return pmi


def cached_arrays(path, what: str, build, *, code=(), **kwargs):
    """``build(path, **kwargs)``: a tuple of numpy arrays computed from the file ``path`` (e.g.
    OpenCASCADE's tessellation of it), computed once per code version and read back bitwise.
    ``what`` names the computation; ``code`` lists the source files of ``build`` (their bytes
    are part of the key)."""
    import numpy as np

    def save(arrays, p):
        with open(p, "wb") as fh:
            np.savez(fh, *arrays)

    def load(p):
        import zipfile

        try:
            with np.load(p, allow_pickle=False) as z:
                return tuple(z[f"arr_{i}"] for i in range(len(z.files)))
        except zipfile.BadZipFile as e:
            raise ValueError(f"{p}: damaged entry") from e

    return _cached(_entry(path, what, kwargs, ".npz", code),
                   lambda: tuple(np.asarray(a) for a in build(path, **kwargs)), save, load)


def load_model_stand_in(path):
    """What a test puts in place of ``shapeverify.cad.load.load_model`` to have a command it
    runs in-process read CAD files through :func:`cached_model` (other files: the real one),
    with the model's features in place (every such command so far -- ``plan``, ``info
    --features``, ``plan_from_pmi`` -- computes them)."""
    from shapeverify.cad.load import _CAD

    return (cached_model(path, features=True) if Path(path).suffix.lower() in _CAD
            else _load_model(path))


def read_pmi_stand_in(path, **kwargs):
    """What a test puts in place of ``shapeverify.cad.pmi.read_pmi``: :func:`cached_pmi`."""
    return cached_pmi(path)
