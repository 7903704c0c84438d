"""A bound on the CPU seconds of a block, for the fuzz tests: a hang burns CPU, a busy machine
only pauses it (hypothesis' wall-clock deadline failed inputs that took 0.3 ms when run again,
with the machine's load at 20 on 2 cores)."""

from __future__ import annotations

import contextlib
import signal


class Hang(Exception):
    """The block used up its CPU seconds."""


@contextlib.contextmanager
def cpu_time_bound(seconds: float, what: str = "did not return"):
    """Raise :class:`Hang` ("<what> within <seconds> s") in the block after ``seconds`` of this
    process' CPU time (``ITIMER_PROF``; main thread only, POSIX)."""
    def _alarm(signum, frame):
        raise Hang(f"{what} within {seconds} s")

    old = signal.signal(signal.SIGPROF, _alarm)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old)
