"""``cli_start.end``: the command line ends without the interpreter's teardown (issue 32 item 7,
~0.3 s of CPU after numpy, scipy and numba) but otherwise as ``sys.exit`` ends it.

The oracle is Python itself: the same script ended by ``sys.exit(code)`` and by ``end(code)``
must give the same exit status, stdout and stderr, with ``atexit`` handlers run, a non-daemon
thread's work finished, and buffered output flushed.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = r"""
import atexit, sys, threading, time
from shapeverify.cli_start import end

atexit.register(lambda: print("atexit ran", flush=False))
def late():
    time.sleep(0.3)
    print("thread done", flush=False)
threading.Thread(target=late).start()          # non-daemon: joined before the process ends
sys.stdout.write("buffered, no newline")         # flushed at the end, not before
sys.stderr.write("on stderr\n")
code = eval(sys.argv[2])
if sys.argv[1] == "end":
    end(code)
else:
    sys.exit(code)
"""


def _run(how: str, code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", SCRIPT, how, code], capture_output=True,
                          text=True, timeout=120)


@pytest.mark.parametrize("code", ["None", "0", "1", "2", "3", "130", "'a message'"])
def test_end_without_teardown_exits_as_sys_exit_does(code):
    want = _run("sys.exit", code)
    got = _run("end", code)
    assert got.returncode == want.returncode
    assert got.stdout == want.stdout
    assert got.stderr == want.stderr
    assert "atexit ran" in got.stdout and "thread done" in got.stdout


def test_python_m_shapeverify_keeps_exit_code_and_output(tmp_path):
    # the module entry point (cli_start.run -> end): --help exits 0 with the whole help text,
    # an unknown command exits 2 with click's message, as before
    ok = subprocess.run([sys.executable, "-m", "shapeverify", "--help"], capture_output=True,
                        text=True, timeout=300, env={**__import__("os").environ,
                                                     "COLUMNS": "120"})
    assert ok.returncode == 0 and "inspect" in ok.stdout and ok.stdout.endswith("\n")
    bad = subprocess.run([sys.executable, "-m", "shapeverify", "no-such-command"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "no-such-command" in bad.stderr
