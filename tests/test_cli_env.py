"""The command line's process settings."""

from __future__ import annotations

import os
import subprocess
import sys


def _blas_threads(env_value):
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if env_value is not None:
        env["OPENBLAS_NUM_THREADS"] = env_value
    code = ("import sys, os; import shapeverify.cli; "
            "print(os.environ.get('OPENBLAS_NUM_THREADS'))")
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def test_cli_runs_blas_single_threaded_unless_the_user_says_otherwise():
    # OpenBLAS's spinning second thread cost an inspection a third of its CPU (bench_inspect)
    assert _blas_threads(None) == "1"
    assert _blas_threads("4") == "4"


def test_numpy_is_not_imported_before_the_cli_sets_it():
    code = ("import sys; import shapeverify; assert 'numpy' not in sys.modules, "
            "'import shapeverify imports numpy before the CLI can set OPENBLAS_NUM_THREADS'")
    subprocess.run([sys.executable, "-c", code], check=True)
