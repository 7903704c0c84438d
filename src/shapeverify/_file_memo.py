"""What a file read gave, remembered while the file is unchanged: off unless a long-lived
process turns it on.

The command line's resident worker (:mod:`shapeverify.cli_worker_server`) serves many commands
that name the same files; it calls :func:`enable` once, and then :func:`shapeverify.load_prepared`
returns the prepared model it already loaded (with the structures it built lazily), and
:func:`shapeverify.pipeline.file_hash` and the CAD summary's cache key the SHA-256 they already
computed, for a file whose path, device, inode, size, mtime and ctime are unchanged.  A
one-shot process (``SHAPEVERIFY_NO_WORKER=1``, a script, the tests) leaves it off and reads
every time.

Examples
--------
>>> import hashlib, tempfile
>>> calls = []
>>> def digest(path):
...     calls.append(path)
...     return hashlib.sha256(open(path, "rb").read()).hexdigest()
>>> memo = FileMemo(keep=2)
>>> with tempfile.NamedTemporaryFile() as f:
...     _ = memo.call(digest, f.name)
...     memo.enable()
...     a, b = memo.call(digest, f.name), memo.call(digest, f.name)
>>> a == b, len(calls)
(True, 2)
"""

from __future__ import annotations

import collections
import os
import threading

__all__ = ["FileMemo", "PREPARED_MODELS", "FILE_HASHES", "enable", "disable", "clear"]


def stat_key(path, *extra):
    """What identifies an unchanged file: its real path, device, inode, size, mtime and ctime
    (ctime changes on every write, even one that restores the mtime), with ``extra``; None for
    anything but a path (bytes, a file object) or a file that cannot be stat'ed."""
    if not isinstance(path, (str, os.PathLike)):
        return None
    try:
        st = os.stat(path)
        key = (os.path.realpath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns,
               st.st_ctime_ns, *extra)
        hash(key)
        return key
    except (OSError, TypeError, ValueError):
        return None


class FileMemo:
    """The last ``keep`` results of ``fn(path, ...)`` per unchanged file (:func:`stat_key`),
    while enabled; disabled (the default) :meth:`call` is ``fn(path, ...)``."""

    def __init__(self, keep: int):
        self.keep = int(keep)
        self._on = False
        self._cache: collections.OrderedDict = collections.OrderedDict()
        self._lock = threading.Lock()

    @property
    def enabled(self) -> bool:
        return self._on

    def enable(self) -> None:
        self._on = True

    def disable(self) -> None:
        """Off, and forget what it held."""
        self._on = False
        self.clear()

    def clear(self) -> None:
        with self._lock:
            self._cache.clear()

    def __len__(self) -> int:
        return len(self._cache)

    def call(self, fn, path, *args, **kwargs):
        """``fn(path, *args, **kwargs)``, or what it returned before for the same unchanged
        file and arguments."""
        key = stat_key(path, fn.__module__, fn.__qualname__, args,
                       tuple(sorted(kwargs.items()))) if self._on else None
        if key is None:
            return fn(path, *args, **kwargs)
        with self._lock:
            if key in self._cache:
                self._cache.move_to_end(key)
                return self._cache[key]
        value = fn(path, *args, **kwargs)
        with self._lock:
            self._cache[key] = value
            while len(self._cache) > self.keep:
                self._cache.popitem(last=False)
        return value


#: prepared models (.svm) by :func:`shapeverify.nearest.load_prepared`: the most recent 4
PREPARED_MODELS = FileMemo(keep=4)
#: files' SHA-256 (the reports' ``model_sha256``, the CAD summary cache's key): the last 64
FILE_HASHES = FileMemo(keep=64)


def enable() -> None:
    """Remember prepared models and file hashes from now on (the resident worker)."""
    PREPARED_MODELS.enable()
    FILE_HASHES.enable()


def disable() -> None:
    PREPARED_MODELS.disable()
    FILE_HASHES.disable()


def clear() -> None:
    PREPARED_MODELS.clear()
    FILE_HASHES.clear()
