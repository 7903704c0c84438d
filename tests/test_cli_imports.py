"""The command line starts light (issue 32 item 7): ``import shapeverify`` and
``import shapeverify.cli`` load none of the heavy libraries (numba, scipy, matplotlib, plotly,
OpenCASCADE); each command imports what it uses when it runs.  Measured in a fresh interpreter,
since this test process has imported them all already."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = ("numba", "llvmlite", "scipy", "matplotlib", "plotly", "OCP", "open3d", "dask",
         "fastapi", "pydantic")

PROBE = r"""
import json, sys
for name in sys.argv[1:]:
    __import__(name)
print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))
"""


def _loaded(*modules: str) -> set[str]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *modules], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return set(json.loads(proc.stdout.splitlines()[-1]))


@pytest.mark.parametrize("modules", [("shapeverify",), ("shapeverify.cli",),
                                     ("shapeverify.cli_start",), ("shapeverify.warmup",)])
def test_importing_the_package_or_the_command_line_loads_no_heavy_library(modules):
    loaded = _loaded(*modules)
    assert "shapeverify" in loaded
    heavy = sorted(loaded.intersection(HEAVY))
    assert not heavy, f"import {', '.join(modules)} loaded {heavy}"


def test_the_public_names_still_resolve_lazily():
    # the lazy __getattr__ of the package gives the real objects
    proc = subprocess.run([sys.executable, "-c",
                           "import shapeverify as sv, sys; "
                           "assert 'numba' not in sys.modules; "
                           "f = sv.inspect; "
                           "assert f.__module__ == 'shapeverify.inspection.inspect', f; "
                           "assert callable(f) and 'numba' in sys.modules; print('ok')"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-3000:]


CLIENT_PROBE = r"""
import json, sys
sys.argv = ["shapeverify", "inspect", "part.svm", "scan.ply", "--tolerance", "0.2"]
from shapeverify.cli_start import main
code = main()
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""

CLIENT_HEAVY = HEAVY + ("numpy", "typer", "click", "rich", "yaml", "shapeverify.cli",
                        "shapeverify.cli_common", "shapeverify.pipeline")


def test_the_client_asks_the_worker_before_importing_anything_heavy(tmp_path, monkeypatch,
                                                                    request):
    # the console entry point with a worker listening: up to the exit code it relays, only the
    # standard library and shapeverify.cli_start / cli_worker are imported (a fake worker
    # answers here: the protocol's frames, exit code 1)
    import socket
    import threading

    from shapeverify import cli_worker

    import shutil
    import tempfile

    sock_dir = Path(tempfile.mkdtemp(prefix="svw-", dir="/tmp"))  # a socket path <= 107 bytes
    request.addfinalizer(lambda: shutil.rmtree(sock_dir, ignore_errors=True))
    monkeypatch.setenv("SHAPEVERIFY_WORKER_DIR", str(sock_dir))
    monkeypatch.delenv("SHAPEVERIFY_NO_WORKER", raising=False)
    path = cli_worker.socket_path()
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(path))
    path.chmod(0o600)
    server.listen(1)
    seen = {}

    def fake_worker():
        conn, _ = server.accept()
        with conn:
            kind, payload = cli_worker._recv(conn)
            seen["request"] = json.loads(payload)
            cli_worker._send(conn, b"Q")
            cli_worker._send(conn, b"A")
            cli_worker._send(conn, b"O", b"verdict: FAIL\n")
            cli_worker._send(conn, b"X", json.dumps({"code": 1, "cpu": 0.25}).encode())

    t = threading.Thread(target=fake_worker, daemon=True)
    t.start()
    try:
        proc = subprocess.run([sys.executable, "-c", CLIENT_PROBE], capture_output=True,
                              text=True, timeout=120, cwd=tmp_path)
    finally:
        t.join(10)
        server.close()
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert lines[0] == "verdict: FAIL"               # the worker's stdout, relayed
    got = json.loads(lines[-1])
    assert got["code"] == 1                          # its exit code
    assert seen["request"]["argv"] == ["inspect", "part.svm", "scan.ply", "--tolerance", "0.2"]
    assert seen["request"]["cwd"] == str(tmp_path)
    loaded = set(got["modules"])
    heavy = sorted(m for m in loaded if m in CLIENT_HEAVY or m.split(".")[0] in CLIENT_HEAVY)
    assert not heavy, f"the client imported {heavy} before handing the command to the worker"
    ours = sorted(m for m in loaded if m.startswith("shapeverify"))
    assert ours == ["shapeverify", "shapeverify.cli_start", "shapeverify.cli_worker"], ours
