"""The inspection service over real HTTP on 127.0.0.1 (issue 9).

Every test talks to a real ``shapeverify serve`` process (a subprocess on a free loopback port).
"""

from __future__ import annotations

import io
import json
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

httpx = pytest.importorskip("httpx")

TOKEN = "s3cret-token"
pytestmark = pytest.mark.slow


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def _npy_header(shape) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buf.getvalue()


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    """Prepared example panel; a clean and a dented simulated scan (~15k points) and a small
    clean scan (~3.7k points) for the load tests, as .npy bytes."""
    from shapeverify.cad.examples import example_part_step
    from shapeverify.cad.load import load_model
    from shapeverify.nearest import prepare
    from shapeverify.simulate import ScanEffects, virtual_scan

    d = tmp_path_factory.mktemp("service")
    model = load_model(example_part_step(d / "panel.step"))
    prepare(model, spacing=1.5).save(d / "panel.svm")
    scans = {}
    for name, pixel, dents in (("clean", 2.0, ()), ("dented", 2.0, [(0.4, 15.0)]), ("small", 4.0, ())):
        sim = virtual_scan(model, pixel=pixel, noise=0.02,
                           effects=ScanEffects(outlier_fraction=0.03, dents=dents),
                           motion=(2.0, 3.0), rng=7)
        scans[name] = _npy(sim.scan)
    return d, scans


class Server:
    """``shapeverify serve`` in a subprocess; waits until /health answers."""

    auth = {"Authorization": f"Bearer {TOKEN}"}

    def __init__(self, svm: Path, db: Path, extra=()):
        self.port = _free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.db = db
        self.scan_dir = db.with_name(db.stem + "-scans")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "shapeverify.cli", "serve", str(svm), "--port", str(self.port),
             "--db", str(db), "--token", TOKEN, *extra], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.time() + 180
        while time.time() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited: {self.proc.stderr.read().decode()[-3000:]}")
            try:
                if httpx.get(self.url + "/health", headers=self.auth, timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                time.sleep(0.2)
        self.stop()
        raise RuntimeError("server did not start within 180 s")

    def post(self, body, params=None, headers=None, **kw):
        h = dict(self.auth)
        h.update(headers or {})
        p = {"model": "panel", "tolerance": 0.2}
        p.update(params or {})
        return httpx.post(self.url + "/inspect", params=p, content=body, headers=h, timeout=120, **kw)

    def get(self, path, **kw):
        return httpx.get(self.url + path, headers=self.auth, timeout=120, **kw)

    def rows(self):
        con = sqlite3.connect(self.db)
        try:
            return con.execute("select id, part, verdict, result_json from inspections order by id").fetchall()
        finally:
            con.close()

    def stop(self, sig=signal.SIGTERM):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stderr:
            self.proc.stderr.close()


@pytest.fixture(scope="module")
def server(panel):
    d, _ = panel
    srv = Server(d / "panel.svm", d / "history.sqlite", extra=["--max-body-mb", "8"])
    yield srv
    srv.stop()


def test_verdicts_history_and_report(server, panel):
    _, scans = panel
    clean = server.post(scans["clean"], params={"part": "P-1"}, headers={"Content-Type": "application/x-npy"})
    assert clean.status_code == 200, clean.text
    body = clean.json()
    assert body["verdict"] == "pass" and isinstance(body["record_id"], int)
    assert body["model"] == "panel" and body["part"] == "P-1" and body["units"] == "mm"
    for key in ("T_model_scan", "registration", "deviation", "tolerance", "regions", "timings"):
        assert key in body
    assert body["tolerance"]["lower"] == -0.2 and body["tolerance"]["upper"] == 0.2
    assert abs(body["deviation"]["mean"]) < 0.02 and body["registration"]["rms"] < 0.1

    dented = server.post(scans["dented"], params={"part": "P-2"})  # no content type: sniffed
    assert dented.status_code == 200, dented.text
    dj = dented.json()
    assert dj["verdict"] == "fail" and len(dj["regions"]) >= 1 and dj["deviation"]["min"] < -0.3

    hist = server.get("/history", params={"part": "P-2"}).json()
    assert [(r["id"], r["verdict"]) for r in hist] == [(dj["record_id"], "fail")]
    assert hist[0]["min"] == pytest.approx(dj["deviation"]["min"])
    everything = server.get("/history", params={"limit": 1000}).json()
    assert {r["id"] for r in everything} >= {body["record_id"], dj["record_id"]}

    rep = server.get(f"/report/{dj['record_id']}")
    assert rep.status_code == 200 and rep.headers["content-type"].startswith("text/html")
    assert "<html" in rep.text.lower() and "plotly" in rep.text.lower() and "fail" in rep.text.lower()
    assert server.get("/report/999999").status_code == 404
    assert server.get("/report/abc").status_code == 404  # not a record id: no such record

    models = server.get("/models").json()
    assert models["panel"]["unit"] == "mm" and models["panel"]["model_points"] > 1000
    assert server.get("/health").json() == {"status": "ok", "models": ["panel"]}


def test_scan_formats(server, panel):
    from shapeverify.io.points import write_ply

    _, scans = panel
    pts = np.load(io.BytesIO(scans["small"]))
    xyz = "\n".join(f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in pts).encode()
    csv_ = ("x,y,z\n" + "\n".join(f"{x:.6f},{y:.6f},{z:.6f}" for x, y, z in pts)).encode()
    ply_bin = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\nproperty float x\n"
               "property float y\nproperty float z\nend_header\n").encode() + pts.astype("<f4").tobytes()
    ply_ascii = write_ply(Path(server.db).with_name("ascii.ply"), pts, binary=False).read_bytes()
    pcd = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {len(pts)}\n"
           f"HEIGHT 1\nPOINTS {len(pts)}\nDATA binary\n").encode() + pts.astype("<f4").tobytes()
    for body, ctype in ((xyz, "text/plain"), (xyz, "application/x-www-form-urlencoded"), (csv_, "text/csv"),
                        (csv_, None), (ply_bin, None), (ply_bin, "application/octet-stream"),
                        (ply_ascii, "application/ply"), (pcd, None)):
        r = server.post(body, headers={"Content-Type": ctype} if ctype else {})
        assert r.status_code == 200 and r.json()["verdict"] == "pass", (ctype, body[:40], r.text)
        assert r.json()["n_points"] == len(pts)


BAD_BODIES = [
    ("empty", b"", None, 422, "empty"),
    ("binary", b"\x00\x01\x02garbage\xff" * 10, "application/octet-stream", 415, "binary"),
    ("text_without_numbers", b"hello world\n", None, 415, "without numbers"),
    ("content_type", b"1 2 3\n", "image/png", 415, "content type"),
    ("multipart", b"--x\r\nContent-Disposition: form-data\r\n\r\n1 2 3\r\n--x--", "multipart/form-data; boundary=x",
     415, "multipart"),
    ("malformed_ply", b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1\n", None, 422, "'y'"),
    ("absurd_count", b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\nproperty float x\n"
     b"property float y\nproperty float z\nend_header\n" + b"\0" * 24, None, 422, "truncated"),
    ("nan_only", b"nan nan nan\nnan nan nan\n", "text/plain", 422, "nan"),
    ("npy_lies", _npy_header((10**10, 3)) + b"\0" * 48, None, 422, "truncated"),
    ("npy_wrong_shape", _npy(np.zeros((10, 2))), "application/x-npy", 422, "shape"),
    ("three_points", b"0 0 0\n1 0 0\n0 1 0\n", None, 422, "at least"),
    ("far_away", _npy(np.random.default_rng(0).uniform(1e4, 1.03e4, (500, 3))), None, 422, "nowhere near"),
    ("in_metres", None, None, 422, "metres"),
]


@pytest.mark.parametrize("name,body,ctype,status,words", BAD_BODIES, ids=[b[0] for b in BAD_BODIES])
def test_bad_scans_get_clear_4xx_and_store_nothing(server, panel, name, body, ctype, status, words):
    if body is None:  # the clean scan in metres
        body = _npy(np.load(io.BytesIO(panel[1]["small"])) * 1e-3)
    rows, files = len(server.rows()), sorted(server.scan_dir.iterdir())
    r = server.post(body, headers={"Content-Type": ctype} if ctype else {})
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    assert isinstance(detail, str) and words.lower() in detail.lower(), detail
    assert "/tmp" not in detail  # the message names the upload, not a temporary file
    assert len(server.rows()) == rows and sorted(server.scan_dir.iterdir()) == files


@pytest.mark.parametrize("params,status,words", [
    ({"tolerance": None}, 422, "tolerance: give tolerance (±mm) or both lower and upper"),
    ({"tolerance": None, "lower": -0.1}, 422, "tolerance: give tolerance"),
    ({"lower": 0.1}, 422, "lower: lower limit is a signed deviation"),
    ({"faces": "0,x"}, 422, "faces: faces must be cad face numbers"),
    ({"faces": "99"}, 422, "face 99 does not exist"),
    ({"min_coverage": 2}, 422, "min_coverage"),
    ({"scan_unit": "furlong"}, 422, "scan_unit: unknown length unit 'furlong'"),
    ({"plan": "characteristics: [1, 2"}, 422, "plan:"),
    ({"tolerance": -1}, 422, "tolerance: input should be greater than 0"),
    ({"tolerance": "nan"}, 422, "tolerance: input should be a finite number"),
    ({"tolerance": "abc"}, 422, "tolerance"),
    ({"max_distance": "inf"}, 422, "max_distance"),
    ({"part": "x" * 500}, 422, "part"),
    ({"model": "nope"}, 404, "unknown model 'nope'; loaded models: ['panel']"),
])
def test_bad_parameters(server, panel, params, status, words):
    p = {"model": "panel", "tolerance": 0.2, **params}
    r = httpx.post(server.url + "/inspect", params={k: v for k, v in p.items() if v is not None},
                   content=panel[1]["small"], headers=server.auth, timeout=60)
    assert r.status_code == status and words in r.json()["detail"].lower(), r.text


def test_body_size_limit(server):
    rows = len(server.rows())
    r = server.post(b"0" * (9 * 1024 * 1024))  # Content-Length over the 8 MB limit
    assert r.status_code == 413 and "limit" in r.json()["detail"]

    def chunks():  # no Content-Length: counted while streaming
        for _ in range(40):
            yield b"1 2 3\n" * 40_000

    try:
        r = server.post(chunks())
        assert r.status_code == 413
    except httpx.HTTPError:
        pass  # the server may close the connection before the client has sent everything
    assert server.get("/health").status_code == 200 and len(server.rows()) == rows


def test_token_and_openapi(server, panel):
    for method, path in (("POST", "/inspect?model=panel&tolerance=0.2"), ("GET", "/health"), ("GET", "/models"),
                         ("GET", "/history"), ("GET", "/report/1"), ("GET", "/openapi.json"), ("GET", "/docs")):
        for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": f"Basic {TOKEN}"},
                        {"Authorization": TOKEN}):
            r = httpx.request(method, server.url + path, headers=headers, content=b"1 2 3\n", timeout=30)
            assert r.status_code == 401, (method, path, headers)
            assert "token" in r.json()["detail"] and r.headers["www-authenticate"] == "Bearer"
    spec = server.get("/openapi.json").json()
    op = spec["paths"]["/inspect"]["post"]
    assert {"401", "404", "408", "413", "415", "422", "504"} <= set(op["responses"])
    assert "application/x-npy" in op["requestBody"]["content"]
    assert {p["name"] for p in op["parameters"]} == {
        "model", "tolerance", "lower", "upper", "evaluation_distance", "max_distance", "faces",
        "min_coverage", "init", "scan_unit", "plan", "part"}
    assert [p.get("deprecated") for p in op["parameters"] if p["name"] == "max_distance"] == [True]
    assert any(s.get("type") == "http" and s.get("scheme") == "bearer"
               for s in spec["components"]["securitySchemes"].values())
    assert {"/health", "/models", "/history", "/report/{record_id}"} <= set(spec["paths"])
    assert server.get("/docs").status_code == 200


def test_concurrent_requests_one_row_each(server, panel):
    """8 clients x 5 requests (one in five malformed): every 200 has exactly one row, with its
    id and part; the 422s have none."""
    _, scans = panel
    before = {r[0] for r in server.rows()}

    def client(i):
        got = []
        for j in range(5):
            bad = j == 2
            r = server.post(b"nan nan nan\n" if bad else scans["small"], params={"part": f"C-{i}-{j}"})
            assert r.status_code == (422 if bad else 200), r.text
            if not bad:
                got.append((r.json()["record_id"], f"C-{i}-{j}", r.json()["verdict"]))
        return got

    with ThreadPoolExecutor(8) as ex:
        answered = [x for got in ex.map(client, range(8)) for x in got]
    assert len(answered) == 32 and len({a[0] for a in answered}) == 32
    new = {r[0]: (r[1], r[2]) for r in server.rows() if r[0] not in before}
    assert new == {rid: (part, verdict) for rid, part, verdict in answered}
    assert all(v == "pass" for _, _, v in answered)


def test_time_limit_gives_504_and_stores_nothing(panel, tmp_path):
    d, scans = panel
    srv = Server(d / "panel.svm", tmp_path / "h.sqlite", extra=["--time-limit", "0.02"])
    try:
        for _ in range(3):
            r = srv.post(scans["clean"])
            assert r.status_code == 504, r.text
            assert "time limit of 0.02 s" in r.json()["detail"]
        assert srv.get("/health").status_code == 200  # the service is still responsive
        time.sleep(1.5)  # let the abandoned worker threads reach their commit point
        assert srv.rows() == [] and list(srv.scan_dir.iterdir()) == []
    finally:
        srv.stop()


def test_history_survives_sigkill(panel, tmp_path):
    """SIGKILL under load, restart: every record whose response was received is there, complete
    (with its scan), the database is intact, and the restarted service works."""
    d, scans = panel
    db = tmp_path / "h.sqlite"
    srv = Server(d / "panel.svm", db)
    received, stop = [], threading.Event()

    def client(i):
        j = 0
        while not stop.is_set():
            try:
                r = srv.post(scans["small"], params={"part": f"K-{i}-{j}"})
            except httpx.HTTPError:
                return
            if r.status_code == 200:
                received.append(r.json()["record_id"])
            j += 1

    with ThreadPoolExecutor(4) as ex:
        futs = [ex.submit(client, i) for i in range(4)]
        t_end = time.time() + 60
        while len(received) < 8 and time.time() < t_end:
            time.sleep(0.02)
        srv.proc.send_signal(signal.SIGKILL)  # in the middle of the load
        stop.set()
        for f in futs:
            f.result()
    srv.stop(signal.SIGKILL)
    assert len(received) >= 8

    srv2 = Server(d / "panel.svm", db)
    try:
        rows = srv2.get("/history", params={"limit": 10_000}).json()
        ids = {r["id"] for r in rows}
        assert set(received) <= ids
        assert len(ids) - len(set(received)) <= 4  # at most the requests in flight at the kill
        con = sqlite3.connect(db)
        assert con.execute("pragma integrity_check").fetchone()[0] == "ok"
        for rid, verdict, text in con.execute("select id, verdict, result_json from inspections"):
            res = json.loads(text)  # no partial record: full result, and its scan is stored
            assert verdict == res["verdict"] == "pass" and res["T_model_scan"] and res["deviation"]["n"] > 0
            assert (srv2.scan_dir / res["scan_file"]).is_file()
        con.close()
        assert srv2.get(f"/report/{received[-1]}").status_code == 200
        r = srv2.post(scans["small"])
        assert r.status_code == 200 and r.json()["record_id"] > max(ids)
    finally:
        srv2.stop()


def test_worker_socket_gets_tcp_nodelay():
    """--workers N: the shared socket is TCP (protocol IPPROTO_TCP), so asyncio sets TCP_NODELAY
    on every accepted connection (uvicorn's own socket has protocol 0 and did not get it: each
    response then waited for the client's delayed ACK, +40 ms)."""
    import asyncio

    from shapeverify.service.server import listen_socket

    sock = listen_socket("127.0.0.1", 0)
    port = sock.getsockname()[1]
    seen = []

    async def main():
        def handler(reader, writer):
            s = writer.get_extra_info("socket")
            seen.append(s.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY))
            writer.close()

        server = await asyncio.start_server(handler, sock=sock)
        async with server:
            r, w = await asyncio.open_connection("127.0.0.1", port)
            await r.read()
            w.close()

    asyncio.run(main())
    assert seen and seen[0] != 0
    with pytest.raises(OSError, match="already in use|--port"):
        busy = listen_socket("127.0.0.1", 0)
        try:
            busy.listen()
            listen_socket("127.0.0.1", busy.getsockname()[1]).listen()
        finally:
            busy.close()


# ------------------------------------------------------- full disk, absurd ids, stalled headers
@pytest.fixture(scope="module")
def local_app(panel, tmp_path_factory):
    """The service app in this process (for monkeypatching), with the panel model."""
    from fastapi.testclient import TestClient

    from shapeverify.service import ServiceConfig, create_app, load_models

    d, _ = panel
    models, hashes = load_models([d / "panel.svm"])
    db = tmp_path_factory.mktemp("local") / "h.sqlite"
    app = create_app(ServiceConfig(models=models, model_hashes=hashes, db_path=db, threads=1))
    with TestClient(app) as client:
        yield client, db, db.with_name(db.stem + "-scans")


def _rows(db) -> int:
    con = sqlite3.connect(db)
    try:
        return con.execute("select count(*) from inspections").fetchone()[0]
    finally:
        con.close()


def test_full_disk_gives_507_and_leaves_no_temporary_file(local_app, panel, monkeypatch):
    import errno

    from shapeverify.report.history import HistoryDB

    client, db, scan_dir = local_app
    _, scans = panel
    params = {"model": "panel", "tolerance": 0.2}
    real_savez = np.savez

    def savez_on_full_disk(fh, **arrays):
        fh.write(b"PK\x03\x04 half an archive")  # the disk fills up while the scan is written
        raise OSError(errno.ENOSPC, "No space left on device")

    with monkeypatch.context() as m:
        m.setattr(np, "savez", savez_on_full_disk)
        r = client.post("/inspect", params=params, content=scans["small"])
    assert r.status_code == 507, r.text
    assert "disk is full" in r.json()["detail"] and "not stored" in r.json()["detail"]
    assert list(scan_dir.iterdir()) == [] and _rows(db) == 0

    def add_on_full_disk(self, *a, **k):
        raise sqlite3.OperationalError("database or disk is full")

    with monkeypatch.context() as m:
        m.setattr(HistoryDB, "add", add_on_full_disk)
        r = client.post("/inspect", params=params, content=scans["small"])
    assert r.status_code == 507, r.text
    assert list(scan_dir.iterdir()) == [] and _rows(db) == 0
    assert np.savez is real_savez
    r = client.post("/inspect", params=params, content=scans["small"])  # space again: stored
    assert r.status_code == 200, r.text
    assert _rows(db) == 1 and [p.suffix for p in scan_dir.iterdir()] == [".npz"]
    spec = client.get("/openapi.json").json()
    assert "507" in spec["paths"]["/inspect"]["post"]["responses"]


@pytest.mark.parametrize("rid", ["99999999999999999999999999", "9223372036854775808", "-1", "0",
                                 "abc", "1e3", "12%2E5", "%20"])
def test_report_of_an_absurd_id_is_404(local_app, rid):
    client, _, _ = local_app
    r = client.get(f"/report/{rid}")
    assert r.status_code == 404, (rid, r.status_code, r.text)
    assert "no stored inspection" in r.json()["detail"]


def _uvicorn_in_thread(app, header_timeout, monkeypatch):
    import uvicorn

    from shapeverify.service.server import HeaderTimeoutProtocol

    monkeypatch.setattr(HeaderTimeoutProtocol, "header_timeout", header_timeout)
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, lifespan="off",
                                           http=HeaderTimeoutProtocol, log_level="error"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.time() + 20
    while not server.started and time.time() < deadline:
        time.sleep(0.02)
    assert server.started
    return server, thread, port


def _closed_after(sock) -> float:
    """Seconds until the server closes ``sock`` (reads and discards whatever it sends)."""
    t0 = time.monotonic()
    sock.settimeout(10)
    while sock.recv(65536):
        pass
    return time.monotonic() - t0


def test_request_headers_that_never_finish_are_dropped_after_the_limit(monkeypatch):
    async def slow_app(scope, receive, send):  # answers after 1 s: longer than the limit
        import asyncio

        await asyncio.sleep(1.0 if scope["path"] == "/slow" else 0.0)
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"ok"})

    server, thread, port = _uvicorn_in_thread(slow_app, 0.5, monkeypatch)
    try:
        with socket.create_connection(("127.0.0.1", port)) as s:  # half a request, then silence
            s.sendall(b"GET /health HTTP/1.1\r\nHost: x\r\nX-Slow: ")
            assert 0.4 < _closed_after(s) < 2.0
        with socket.create_connection(("127.0.0.1", port)) as s:
            s.sendall(b"GET /slow HTTP/1.1\r\nHost: x\r\n\r\n")  # a request in progress stays
            s.settimeout(5)
            assert s.recv(65536).startswith(b"HTTP/1.1 200")
            s.sendall(b"GET / HTTP/1.1\r\nHo")  # kept alive, then a stalled second request
            assert _closed_after(s) < 2.0  # (uvicorn alone would wait for ever)
    finally:
        server.should_exit = True
        thread.join(10)


def test_init_parameter_gives_the_start_pose_or_a_clear_422(local_app, panel):
    client, _, _ = local_app
    _, scans = panel
    base = {"model": "panel", "tolerance": 0.2}
    ok = client.post("/inspect", params={**base, "init": "identity"}, content=scans["clean"])
    assert ok.status_code == 200, ok.text
    eye = ",".join(str(float(v)) for v in np.eye(4).ravel())
    given = client.post("/inspect", params={**base, "init": eye}, content=scans["clean"])
    assert given.status_code == 200 and given.json()["verdict"] == ok.json()["verdict"]
    for bad in ("sideways", "1,2,3", ",".join(["nan"] * 16)):
        r = client.post("/inspect", params={**base, "init": bad}, content=scans["clean"])
        assert r.status_code == 422 and "16 comma-separated numbers" in r.json()["detail"]


def test_a_bug_is_a_500_that_says_so_and_stores_nothing_but_bad_input_stays_422(local_app, panel,
                                                                                 monkeypatch):
    from fastapi.testclient import TestClient

    import shapeverify.inspection

    client, db, scan_dir = local_app
    _, scans = panel
    params = {"model": "panel", "tolerance": 0.2}
    before = _rows(db)
    plain = TestClient(client.app, raise_server_exceptions=False)  # the answer a client gets

    def numpy_bug(*a, **k):
        return np.zeros(3) + np.zeros(4)  # a ValueError raised inside numpy: a bug, not bad input

    def type_bug(*a, **k):
        raise TypeError("unsupported operand type(s)")

    for bug, what in ((numpy_bug, "ValueError: operands could not be broadcast"),
                      (type_bug, "TypeError: unsupported operand")):
        with monkeypatch.context() as m:
            m.setattr(shapeverify.inspection, "inspect", bug)
            r = plain.post("/inspect", params=params, content=scans["small"])
        assert r.status_code == 500, r.text
        detail = r.json()["detail"]
        assert detail.startswith("internal error (a bug in shapeverify, please report it)")
        assert what in detail
    assert _rows(db) == before
    r = plain.post("/inspect", params=params, content=b"1 2 3\n4 5\n")  # the project's own error
    assert r.status_code == 422 and "request body" in r.json()["detail"]


# ------------------------------------------------------- reports redraw what was decided
@pytest.fixture(scope="module")
def report_app(panel, tmp_path_factory):
    """The service app in this process with a history of its own."""
    from fastapi.testclient import TestClient

    from shapeverify.service import ServiceConfig, create_app, load_models

    d, _ = panel
    models, hashes = load_models([d / "panel.svm"])
    db = tmp_path_factory.mktemp("reports") / "h.sqlite"
    app = create_app(ServiceConfig(models=models, model_hashes=hashes, db_path=db, threads=1))
    with TestClient(app) as client:
        yield client, db, db.with_name(db.stem + "-scans")


def _banner(page: str) -> tuple[str, list]:
    """(verdict, reasons) as the report's banner shows them."""
    import html
    import re

    m = re.search(r'<div class="banner" id="verdict"[^>]*>\s*<h1>(.*?)</h1>(.*?)</div>\s*'
                  r'<div class="grid">', page, re.S)
    assert m, "no verdict banner in the report"
    reasons = [html.unescape(r) for r in re.findall(r"<li>(.*?)</li>", m.group(2), re.S)]
    return html.unescape(m.group(1)).lower(), reasons


def test_report_redraws_the_stored_verdict_and_reasons_of_every_kind(report_app, panel,
                                                                     monkeypatch):
    """Issue 29 item 5: ``/report/{id}`` draws the stored result; it never inspects again (a
    stored 'error: the scan fits at no pose' was redrawn as 'incomplete' from a rebuilt
    registration without its robust scale)."""
    import shapeverify.inspection as insp

    client, db, scan_dir = report_app
    _, scans = panel
    small = np.load(io.BytesIO(scans["small"]))
    rng = np.random.default_rng(0)
    bodies = {
        "pass": scans["small"],
        "fail": scans["dented"],
        "incomplete": _npy(small[small[:, 0] < np.percentile(small[:, 0], 10)]),
        "error": _npy(rng.uniform(small.min(axis=0), small.max(axis=0), (3000, 3))),
    }
    stored = {}
    for kind, body in bodies.items():
        r = client.post("/inspect", params={"model": "panel", "tolerance": 0.2, "part": kind},
                        content=body)
        assert r.status_code == 200, r.text
        j = r.json()
        assert j["verdict"] == kind, (kind, j["reasons"])
        stored[kind] = j
    assert stored["error"]["decision"]["rule"] == "registration"
    assert "fit" in stored["error"]["reasons"][0] and "scale" in stored["error"]["registration"]

    def no_inspection(*a, **k):
        raise AssertionError("the report inspected the scan again")

    monkeypatch.setattr(insp, "inspect_registered", no_inspection)
    monkeypatch.setattr(insp, "inspect", no_inspection)
    for kind, j in stored.items():
        page = client.get(f"/report/{j['record_id']}")
        assert page.status_code == 200, page.text
        verdict, reasons = _banner(page.text)
        assert verdict == kind and reasons == j["reasons"], (kind, verdict, reasons, j["reasons"])
        # the figures are the stored ones too
        assert f"{j['deviation']['n']:,}" in page.text
    con = sqlite3.connect(db)
    try:
        rows = dict(con.execute("select part, verdict from inspections").fetchall())
    finally:
        con.close()
    assert rows == {k: k for k in stored}
    # the history by model: the panel's records, none of an unknown model
    hist = client.get("/history", params={"model": "panel", "limit": 100}).json()
    assert {r["part"] for r in hist} >= set(stored)
    assert {r["verdict"] for r in hist if r["part"] == "fail"} == {"fail"}
    fail_row = [r for r in hist if r["part"] == "fail"][0]
    assert fail_row["min"] == pytest.approx(stored["fail"]["deviation"]["min"])
    assert fail_row["lower"] == -0.2 and fail_row["upper"] == 0.2
    r = client.get("/history", params={"model": "beef"})
    assert r.status_code == 404 and "no records of model" in r.json()["detail"]


def test_report_of_a_record_stored_before_the_arrays_keeps_its_decision(report_app, panel):
    """A scan archive of the previous version (points and weights only): the figures are
    recomputed at the stored pose, the verdict and reasons stay the stored ones."""
    client, db, scan_dir = report_app
    _, scans = panel
    small = np.load(io.BytesIO(scans["small"]))
    rng = np.random.default_rng(0)
    body = _npy(rng.uniform(small.min(axis=0), small.max(axis=0), (3000, 3)))
    r = client.post("/inspect", params={"model": "panel", "tolerance": 0.2}, content=body)
    assert r.status_code == 200, r.text
    j = r.json()
    assert j["verdict"] == "error"
    path = scan_dir / j["scan_file"]
    with np.load(path) as z:
        points, weights = z["points"], z["weights"]
    with open(path, "wb") as fh:
        np.savez(fh, points=points, weights=weights)
    page = client.get(f"/report/{j['record_id']}")
    assert page.status_code == 200, page.text
    assert _banner(page.text) == ("error", j["reasons"])
    assert "figures recomputed at the stored pose" in page.text
