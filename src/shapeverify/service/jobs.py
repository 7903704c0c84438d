"""Running the service's work on its inspection threads, within the request's time limit.

A request hands its work to :class:`Runner`, which runs it on a thread pool and answers 504 at
the deadline (unless the job's commit has already begun, see :class:`Job`).  The runner is also
where errors become HTTP answers: the project's errors about the input become 415 / 422, a full
disk 507; anything else is a bug and propagates (a 500, logged with its traceback).
"""

from __future__ import annotations

import asyncio
import errno
import logging
import sqlite3
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from fastapi import HTTPException

from shapeverify.errors import UnsupportedFormatError, is_input_error

log = logging.getLogger(__name__)


class Cancelled(Exception):
    """The request was answered with a time-out; the worker stops without storing anything."""


class Job:
    """Hand-over between a request (which may time out) and its worker thread.

    States: ``queued`` -> ``running`` -> ``committing``, or ``cancelled`` (from queued or
    running).  The worker calls :meth:`check` between stages and :meth:`begin_commit` before it
    stores anything; the request calls :meth:`cancel` at its deadline.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self.state = "queued"

    def _move(self, allowed: tuple, new: str) -> bool:
        with self._lock:
            if self.state not in allowed:
                return False
            self.state = new
            return True

    def start(self) -> bool:
        return self._move(("queued",), "running")

    def begin_commit(self) -> bool:
        return self._move(("running",), "committing")

    def cancel(self) -> bool:
        """True if the job will store nothing; False if its commit has already begun."""
        return self._move(("queued", "running"), "cancelled")

    def check(self, *_args) -> None:  # also the ``progress`` callback of inspect()
        if self.state == "cancelled":
            raise Cancelled


def disk_full(exc: BaseException) -> bool:
    """Whether storing failed because the disk (or the user's quota) is full."""
    if isinstance(exc, OSError):
        return exc.errno in (errno.ENOSPC, errno.EDQUOT)
    return isinstance(exc, sqlite3.OperationalError) and "full" in str(exc).lower()


class Runner:
    """The inspection threads of one service process and the per-request time limit (s)."""

    def __init__(self, threads: int, time_limit_s: float):
        self.limit = float(time_limit_s)
        self.executor = ThreadPoolExecutor(max(1, int(threads)), thread_name_prefix="inspect")

    def deadline(self) -> float:
        """The deadline (``time.monotonic()``) of a request that starts now."""
        return time.monotonic() + self.limit

    def shutdown(self) -> None:
        self.executor.shutdown(wait=True, cancel_futures=True)

    async def run(self, deadline: float, fn, *args):
        """Run ``fn(job, *args)`` on the inspection threads; 504 at the deadline unless the
        job's commit has already begun (then its result is awaited and answered)."""
        job = Job()
        fut = asyncio.get_running_loop().run_in_executor(self.executor, _unless_cancelled, fn,
                                                         job, *args)
        try:
            try:
                return await asyncio.wait_for(asyncio.shield(fut), max(0.0, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                if job.cancel():
                    # the worker stops at its next check; its outcome is of no interest any more
                    fut.add_done_callback(lambda f: f.cancelled() or f.exception())
                    raise HTTPException(504, f"the request exceeded the time limit of "
                                             f"{self.limit:g} s; nothing was stored") from None
                return await fut
        except HTTPException:
            raise
        except UnsupportedFormatError as exc:
            raise HTTPException(415, str(exc)) from None
        except (OSError, sqlite3.OperationalError) as exc:
            if not disk_full(exc):
                raise
            log.error("disk full, request not stored: %s", exc)
            raise HTTPException(507, "the server's disk is full: the result was not stored; free "
                                     "space on the server and send the request again") from None
        except Exception as exc:
            if not is_input_error(exc):
                raise  # a bug: the app's handler answers 500 and logs the traceback
            raise HTTPException(422, str(exc)) from None


def _unless_cancelled(fn, job: Job, *args):
    try:
        return fn(job, *args)
    except Cancelled:
        return None
