"""glibc's malloc held lean while ``prepare`` runs (private; :func:`lean_malloc`)."""

from __future__ import annotations

from contextlib import contextmanager
from functools import lru_cache

__all__ = ["lean_malloc", "release_memory", "PREPARE_MMAP_THRESHOLD"]

_M_MMAP_THRESHOLD = -3  # glibc mallopt parameter
#: while ``prepare`` runs, arrays from this size on get their own memory map (glibc)
PREPARE_MMAP_THRESHOLD = 1 << 20
_M_TRIM_THRESHOLD = -1
_AFTER_MMAP_THRESHOLD = 32 << 20  # the ceiling of glibc's own (dynamic) threshold, 64 bit
_AFTER_TRIM_THRESHOLD = 64 << 20  # glibc's trim threshold with it (twice the mmap threshold)


@contextmanager
def lean_malloc(threshold: int = PREPARE_MMAP_THRESHOLD):
    """Within the block (entered with :func:`release_memory`), glibc's malloc serves every
    allocation of ``threshold`` bytes or more with its own memory map, returned to the system
    when freed (process-wide while the block runs; nothing is done on other C libraries).

    glibc raises its mmap threshold up to 32 MB after the first large array is freed, so the
    many 1-32 MB temporaries of a preparation then come from the heap, whose freed holes the
    process keeps: the 1M-point impeller's peak RSS was about 220 MB higher than with the
    threshold held down.  Afterwards the thresholds are set where glibc's own adjustment
    ends up after the first large arrays are freed (mmap 32 MB, trim 64 MB; they are no
    longer adjusted).
    """
    libc = _glibc()
    if libc is None:
        yield
        return
    release_memory()
    libc.mallopt(_M_MMAP_THRESHOLD, int(threshold))
    try:
        yield
    finally:
        libc.mallopt(_M_MMAP_THRESHOLD, _AFTER_MMAP_THRESHOLD)
        libc.mallopt(_M_TRIM_THRESHOLD, _AFTER_TRIM_THRESHOLD)


def release_memory() -> None:
    """Return the free pages of glibc's heap to the system (``malloc_trim(0)``; else nothing)."""
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)


@lru_cache(maxsize=1)
def _glibc():
    """The C library when it is glibc (it has ``mallopt``), else None."""
    import ctypes
    import platform

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        libc = ctypes.CDLL(None)
        libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
        libc.malloc_trim.argtypes = (ctypes.c_size_t,)
        return libc
    except (OSError, AttributeError):
        return None
