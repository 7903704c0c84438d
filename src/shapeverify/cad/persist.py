"""Save a model to one ``.svmodel`` file and load it back (so the CAD import happens once).

The file is a plain ``.npz`` archive (``numpy.savez``, uncompressed, loaded without pickle;
its ``meta`` holds the SHA-256 of the other arrays, :func:`payload_digest`, compared on loading):
every face's arrays are concatenated into a few flat arrays with offsets, so loading costs a
handful of reads and one object construction per face.  Arrays round-trip bit for bit.

Layout (F faces, L loops, K loop vertices; format version 1)
-------------------------------------------------------------
``meta``            uint8 JSON: format tag, version, unit, source, kind, counts
``scale_to_mm``     (1,) float64
``degrees``         (F, 2) int64       (degree_u, degree_v)
``shapes``          (F, 2) int64       control-net shape (nu, nv)
``reversed``        (F,) bool
``rational``        (F,) bool
``knots_u``/``knots_v``   concatenated knot vectors, with ``knots_u_len``/``knots_v_len`` (F,)
``control``         (sum nu*nv, 3) float64, row-major per face
``weights``         (sum over rational faces of nu*nv,) float64
``face_nloops``     (F,) int64        loops per face (outer first)
``loop_len``        (L,) int64        vertices per loop
``loops``           (K, 2) float64;   ``loop_free`` (K,) bool
``vertices``, ``triangles``, ``cloud_normals``   present only when the model has them.

``meta`` holds ``face_names`` (one name or null per face) only when some face has a name from
the CAD file; files without it (all files written before names were read) load with
``face_names=None``; likewise ``supplemental`` (the indices of supplemental faces,
:attr:`Model.supplemental`) only when there are some.

:func:`model_to_arrays` / :func:`model_from_arrays` expose the same dictionary so that other
files (e.g. a prepared closest-point structure) can embed a model.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
import tokenize
import zipfile
import zlib
from pathlib import Path

import numpy as np

from shapeverify.errors import EmptyModelError, ModelFileError

__all__ = ["save_model", "load_saved_model", "model_to_arrays", "model_from_arrays",
           "payload_digest", "FORMAT_TAG", "FORMAT_VERSION", "DAMAGED_FILE_ERRORS"]

#: what numpy, zipfile and the array checks raise on a damaged, truncated or foreign archive
#: (bit flips fail zipfile's CRC check: ``BadZipFile``; truncation: ``BadZipFile``/``EOFError``;
#: a flipped flag bit: ``NotImplementedError``/``RuntimeError`` ("encrypted"); wrong shapes or
#: dtypes: ``ValueError``/``IndexError``/``TypeError``; a damaged ``.npy`` header that numpy
#: parses with ``tokenize``/``ast``: ``TokenError``/``SyntaxError``, found by the .svm fuzz)
DAMAGED_FILE_ERRORS = (ValueError, LookupError, TypeError, AttributeError, RuntimeError, OSError,
                       EOFError, zipfile.BadZipFile, zlib.error, struct.error, OverflowError,
                       MemoryError, tokenize.TokenError, SyntaxError)



def damage_text(exc: BaseException) -> str:
    """``exc`` as a message part for a damaged file, without numpy's advice to load unsafely.

    numpy refuses object arrays with "... load it unsafely using the `allow_pickle=`
    keyword": shapeverify never writes such arrays, and loading pickled data from a file of
    unknown origin can run any code, so the message says what the file holds instead.
    """
    text = str(exc)
    if "allow_pickle" in text or "pickle" in text.lower():
        return "it holds Python objects (pickled data), which shapeverify files never contain"
    return f"{type(exc).__name__}: {text}"


_REDO = ("make it again from the CAD file (`shapeverify prepare CAD -o MODEL.svm`, or "
         "`load_model(CAD).save(PATH)` for a .svmodel)")

FORMAT_TAG = "shapeverify-model"
FORMAT_VERSION = 1


def payload_digest(arrays) -> str:
    """SHA-256 (hex) of every array but ``meta``: name, dtype, shape and bytes, in name order.

    The checksum a ``.svmodel`` and a ``.svm`` file keep in their header (``meta["sha256"]``)
    and compare on loading (issue 33 row 5); ``arrays``: a mapping of name -> array."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays.keys() if k != "meta"):
        a = np.ascontiguousarray(np.asarray(arrays[name]))
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.reshape(-1).view(np.uint8) if a.size else b"")
    return h.hexdigest()


def model_to_arrays(model) -> dict:
    """Flatten a :class:`~shapeverify.cad.model.Model` into a dict of numpy arrays (no objects).

    Parameters
    ----------
    model : Model

    Returns
    -------
    dict[str, numpy.ndarray]
        See the module docstring for the keys.
    """
    faces = model.faces
    surfs = [f.surface for f in faces]
    meta = {"format": FORMAT_TAG, "version": FORMAT_VERSION, "unit": model.unit,
            "source": model.source, "kind": model.kind, "n_faces": len(faces),
            "n_faces_in_file": model.n_faces_in_file, "skipped_faces": list(model.skipped_faces)}
    if model.face_names is not None:
        meta["face_names"] = list(model.face_names)
    if model.open_seams:
        meta["open_seams"] = list(model.open_seams)
    if model.supplemental:
        meta["supplemental"] = list(model.supplemental)
    a = {
        "meta": np.frombuffer(json.dumps(meta).encode("utf-8"), dtype=np.uint8),
        "scale_to_mm": np.array([model.scale_to_mm], dtype=np.float64),
        "degrees": np.array([[s.degree_u, s.degree_v] for s in surfs], np.int64).reshape(-1, 2),
        "shapes": np.array([s.control.shape[:2] for s in surfs], np.int64).reshape(-1, 2),
        "reversed": np.array([f.reversed for f in faces], dtype=bool),
        "rational": np.array([s.weights is not None for s in surfs], dtype=bool),
        "knots_u": _cat([s.knots_u for s in surfs], (0,)),
        "knots_u_len": np.array([len(s.knots_u) for s in surfs], np.int64),
        "knots_v": _cat([s.knots_v for s in surfs], (0,)),
        "knots_v_len": np.array([len(s.knots_v) for s in surfs], np.int64),
        "control": _cat([s.control.reshape(-1, 3) for s in surfs], (0, 3)),
        "weights": _cat([s.weights.ravel() for s in surfs if s.weights is not None], (0,)),
        "face_nloops": np.array([len(f.loops) for f in faces], np.int64),
        "loop_len": np.array([len(lp) for f in faces for lp in f.loops], np.int64),
        "loops": _cat([np.asarray(lp, np.float64) for f in faces for lp in f.loops], (0, 2)),
        "loop_free": _cat([np.asarray(fr, bool) for f in faces for fr in f.loop_free], (0,),
                          bool),
    }
    for name in ("vertices", "triangles", "cloud_normals"):
        arr = getattr(model, name)
        if arr is not None:
            a[name] = np.asarray(arr)
    if model.faces or model.vertices is not None:
        a["bounds"] = np.asarray(model.bounds, dtype=np.float64)  # trim-following: costly to redo
    return a


def model_from_arrays(a, where: str = "<arrays>"):
    """Rebuild a :class:`~shapeverify.cad.model.Model` from :func:`model_to_arrays` output.

    Parameters
    ----------
    a : mapping of str -> numpy.ndarray (a dict or an open ``NpzFile``)
    where : str
        Name used in error messages (the file path).

    Raises
    ------
    ModelFileError
        Missing keys, wrong format tag or version, inconsistent sizes.
    EmptyModelError
        A CAD model with no faces.
    """
    from shapeverify.cad.model import Face, Model
    from shapeverify.cad.nurbs import NurbsSurface

    try:
        meta = json.loads(bytes(np.asarray(a["meta"], dtype=np.uint8)).decode("utf-8"))
    except (KeyError, ValueError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"{where}: not a shapeverify model file (no readable 'meta': "
                             f"{exc})") from None
    if meta.get("format") != FORMAT_TAG:
        raise ModelFileError(f"{where}: not a shapeverify model file (format tag "
                             f"{meta.get('format')!r})")
    if meta.get("version") != FORMAT_VERSION:
        raise ModelFileError(f"{where}: model file version {meta.get('version')!r} is not "
                             f"supported (this shapeverify reads version {FORMAT_VERSION}); "
                             "re-import the CAD file")
    try:
        deg, shp = a["degrees"], a["shapes"]
        rev, rat = a["reversed"], a["rational"]
        ku, kul = a["knots_u"], a["knots_u_len"]
        kv, kvl = a["knots_v"], a["knots_v_len"]
        ctrl, wts = a["control"], a["weights"]
        nloops, llen = a["face_nloops"], a["loop_len"]
        loops, lfree = a["loops"], a["loop_free"]
        scale = float(a["scale_to_mm"][0])
        opt = {k: (a[k] if k in a else None) for k in ("vertices", "triangles", "cloud_normals")}
    except KeyError as exc:
        raise ModelFileError(f"{where}: model file is missing array {exc}") from None
    n = int(meta.get("n_faces", -1))
    if not (len(deg) == len(shp) == len(rev) == len(rat) == len(kul) == len(kvl)
            == len(nloops) == n):
        raise ModelFileError(f"{where}: model file is inconsistent (face arrays of different "
                             f"lengths, expected {n})")
    if meta.get("kind") == "cad" and n == 0:
        raise EmptyModelError(f"{where}: the saved CAD model has no faces")
    ncp = shp[:, 0] * shp[:, 1]
    ku_off = _offsets(kul)
    kv_off = _offsets(kvl)
    c_off = _offsets(ncp)
    w_off = _offsets(np.where(rat, ncp, 0))
    l_off = _offsets(nloops)
    v_off = _offsets(llen)
    if (ku_off[-1] != len(ku) or kv_off[-1] != len(kv) or c_off[-1] != len(ctrl)
            or w_off[-1] != len(wts) or l_off[-1] != len(llen) or v_off[-1] != len(loops)
            or len(lfree) != len(loops)):
        raise ModelFileError(f"{where}: model file is inconsistent (array sizes do not match "
                             "the offsets)")
    faces = []
    try:
        for i in range(n):
            nu, nv = int(shp[i, 0]), int(shp[i, 1])
            w = wts[w_off[i]:w_off[i + 1]].reshape(nu, nv) if rat[i] else None
            surf = NurbsSurface(int(deg[i, 0]), int(deg[i, 1]), ku[ku_off[i]:ku_off[i + 1]],
                                kv[kv_off[i]:kv_off[i + 1]],
                                ctrl[c_off[i]:c_off[i + 1]].reshape(nu, nv, 3), w)
            lps = tuple(loops[v_off[j]:v_off[j + 1]] for j in range(l_off[i], l_off[i + 1]))
            frs = tuple(lfree[v_off[j]:v_off[j + 1]] for j in range(l_off[i], l_off[i + 1]))
            faces.append(Face(surf, lps, frs, bool(rev[i])))
        model = Model(faces=tuple(faces), unit=meta["unit"], scale_to_mm=scale,
                      source=meta["source"], kind=meta["kind"],
                      n_faces_in_file=meta.get("n_faces_in_file"),
                      skipped_faces=tuple(meta.get("skipped_faces") or ()),
                      open_seams=tuple(meta.get("open_seams") or ()),
                      supplemental=tuple(meta.get("supplemental") or ()),
                      face_names=_face_names(meta.get("face_names"), n, where), **opt)
        if "bounds" in a and np.shape(a["bounds"]) == (2, 3):
            b = np.array(a["bounds"], dtype=np.float64)
            b.setflags(write=False)
            model.__dict__["bounds"] = b  # prime Model.bounds (a cached_property) with the stored box
        return model
    except (ValueError, IndexError, TypeError) as exc:
        raise ModelFileError(f"{where}: model file holds invalid data ({exc})") from None


def save_model(model, path) -> Path:
    """Write ``model`` to one file (by convention ``*.svmodel``; read it with
    :func:`load_saved_model` or ``sv.load_model``).

    The file is written to a temporary name and renamed, so a crash never leaves half a file.

    Parameters
    ----------
    model : Model
    path : str or os.PathLike

    Returns
    -------
    pathlib.Path
        The written path.
    """
    path = Path(path)
    arrays = model_to_arrays(model)
    meta = json.loads(bytes(arrays["meta"]).decode("utf-8"))
    meta["sha256"] = payload_digest(arrays)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode("utf-8"), dtype=np.uint8)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def load_saved_model(path):
    """Read a model written by :func:`save_model`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Model
        Same faces, unit, scale, source and kind; every array bitwise equal to the saved one.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ModelFileError
        Empty, truncated, damaged (bit flips fail the archive's CRC check) or foreign file;
        unsupported format version.  The message names the file and says how to make it again.
    EmptyModelError
        A saved CAD model without faces.
    """
    path = Path(path)
    if not path.exists():
        import errno
        raise FileNotFoundError(errno.ENOENT, f"{path}: file not found", str(path))
    if path.stat().st_size == 0:
        raise ModelFileError(f"{path}: model file is empty (0 bytes); {_REDO}")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        _check_digest(arrays, path)
        return model_from_arrays(arrays, str(path))
    except ModelFileError as exc:
        raise ModelFileError(f"{exc}; {_REDO}") from None
    except EmptyModelError:
        raise
    except DAMAGED_FILE_ERRORS as exc:
        raise ModelFileError(f"{path}: not a readable shapeverify model file, damaged or "
                             f"truncated ({damage_text(exc)}); {_REDO}") from None


def _check_digest(arrays, path) -> None:
    """Compare a ``.svmodel``'s checksum (files written before it existed have none)."""
    try:
        digest = json.loads(bytes(np.asarray(arrays["meta"], np.uint8)).decode("utf-8")).get(
            "sha256")
    except (KeyError, ValueError, UnicodeDecodeError, AttributeError):
        return  # model_from_arrays says what is wrong with the header
    if digest is not None and digest != payload_digest(arrays):
        raise ModelFileError(f"{path}: model file is damaged: its content does not match the "
                             "checksum (SHA-256) written with it")


def _face_names(names, n: int, where: str):
    """The ``face_names`` of a model file's meta (absent in files written before it existed)."""
    if names is None:
        return None
    if not isinstance(names, list) or len(names) != n or not all(
            x is None or isinstance(x, str) for x in names):
        raise ModelFileError(f"{where}: model file is inconsistent (face_names must be a list "
                             f"of {n} names or nulls)")
    return tuple(names)


def _cat(arrays, empty_shape, dtype=np.float64):
    return np.concatenate(arrays) if arrays else np.empty(empty_shape, dtype)


def _offsets(counts):
    out = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(counts, out=out[1:])
    return out
