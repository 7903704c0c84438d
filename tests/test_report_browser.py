"""The HTML report in a real browser: headless Chromium opens it offline, without console errors,
the 3D view (WebGL canvas) and the histogram render, and a screenshot is not blank.

Chromium (the Debian package ``chromium``, nothing else: the test drives the browser itself, no
chromium-driver) is never installed from inside pytest, where a silent install of a hundred
packages hid for minutes behind the dots (issue 32).  ``make test`` runs ``make browser`` first,
which says what it installs and installs it when it can; here, a missing Chromium skips the
tests with the reason and the command that installs it.  Console errors are caught
by a small script injected at the top of a copy of the report (it records ``console.error``
calls, uncaught exceptions and unhandled promise rejections into an attribute of ``<html>``,
which ``--dump-dom`` then shows); Chromium's own log is also scanned for ``Uncaught``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest

from shapeverify.cad.model import Face, Model
from shapeverify.cad.nurbs import NurbsSurface
from shapeverify.inspection import inspect_registered
from shapeverify.report import write_html_report

pytestmark = pytest.mark.slow

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader",       # software WebGL for plotly's 3D view (no GPU here)
         "--enable-logging=stderr", "--v=0", "--virtual-time-budget=8000"]

HOOK = """<script>
window.__svErrors = [];
(function () {
  var orig = console.error;
  console.error = function () {
    window.__svErrors.push(Array.prototype.map.call(arguments, String).join(" "));
    return orig.apply(console, arguments);
  };
  window.addEventListener("error", function (e) { window.__svErrors.push(String(e.message)); });
  window.addEventListener("unhandledrejection", function (e) {
    window.__svErrors.push("Unhandled rejection " + e.reason); });
  setInterval(function () {
    document.documentElement.setAttribute("data-sv-errors", JSON.stringify(window.__svErrors));
  }, 100);
})();
</script>"""


#: the command the skip reason gives (the Makefile's ``browser`` target runs it, saying so first)
INSTALL = "apt-get install --no-install-recommends chromium"


@pytest.fixture(scope="session")
def chromium():
    exe = shutil.which("chromium")
    if exe is None:
        pytest.skip(f"Chromium is not installed: `make browser` (as root) or `{INSTALL}` "
                    "installs it (25 Debian packages, about 115 MB to download)")
    return exe


def _plane_prep():
    faces = []
    for x0, x1 in ((0.0, 50.0), (50.0, 100.0)):
        ctrl = np.array([[[x0, 0, 0], [x0, 60, 0]], [[x1, 0, 0], [x1, 60, 0]]], float)
        loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        free = np.array([True, x1 == 100.0, True, x0 == 0.0])
        faces.append(Face(NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl), (loop,), (free,)))

    def closest(q, exact=False):
        foot = q.copy()
        foot[:, 0] = np.clip(q[:, 0], 0, 100.0)
        foot[:, 1] = np.clip(q[:, 1], 0, 60.0)
        foot[:, 2] = 0.0
        d = np.linalg.norm(q - foot, axis=1) * np.where(q[:, 2] >= 0, 1.0, -1.0)
        return SimpleNamespace(points=foot, normals=np.tile([0.0, 0.0, 1.0], (len(q), 1)),
                               distances=d, face=(foot[:, 0] > 50).astype(np.int32), uv=foot[:, :2],
                               index=np.zeros(len(q), np.int64),
                               on_boundary=(foot[:, 0] != q[:, 0]) | (foot[:, 1] != q[:, 1]))

    x, y = np.meshgrid(np.arange(0.5, 100.0, 1.0), np.arange(0.5, 60.0, 1.0))   # model points
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    return SimpleNamespace(model=Model(tuple(faces), source="browser test plane"), closest=closest,
                           points=SimpleNamespace(points=pts, face=(pts[:, 0] > 50).astype(np.int32),
                                                  spacing=1.0),
                           spacing=1.0, n_points=len(pts))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    rng = np.random.default_rng(11)
    x, y = np.meshgrid(np.arange(1, 99, 0.5), np.arange(1, 59, 0.5))
    x, y = x.ravel(), y.ravel()
    z = -0.4 * np.exp(-((x - 30) ** 2 + (y - 20) ** 2) / 18.0) + rng.normal(0, 0.02, x.size)
    scan = np.column_stack([x, y, z])
    reg = SimpleNamespace(T_model_scan=np.eye(4), rms=0.02, iterations=8, converged=True,
                          inlier_fraction=0.97, weights=np.ones(len(scan)), message="")
    prep = _plane_prep()
    res = inspect_registered(prep, scan, reg, tolerance=0.2)
    out = tmp_path_factory.mktemp("browser")
    path = write_html_report(res, prep, scan, out / "report.html")
    page = path.read_text(encoding="utf-8")
    hooked = out / "report_hooked.html"
    hooked.write_text(page.replace("<head>", "<head>" + HOOK, 1), encoding="utf-8")
    return hooked


def _run(chromium, args, tmp_path, timeout=180):
    profile = tmp_path / "chrome-profile"            # a fresh profile for every run
    cmd = [chromium, *FLAGS, f"--user-data-dir={profile}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "HOME": str(tmp_path)})


def test_report_renders_without_console_errors(chromium, report, tmp_path):
    proc = _run(chromium, ["--dump-dom", report.as_uri()], tmp_path)
    dom = proc.stdout
    assert proc.returncode == 0, proc.stderr[-2000:]
    m = re.search(r'data-sv-errors="([^"]*)"', dom)
    assert m is not None, "the console hook did not run"
    errors = json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert errors == []
    assert "Uncaught" not in proc.stderr
    # plotly rendered both figures: the 3D view has its WebGL canvas, the histogram its SVG bars
    # (look at the rendered elements only: plotly.js's own source is in the DOM as script text)
    dom = re.sub(r"<script\b.*?</script>", "", dom, flags=re.S)
    view = dom[dom.index('id="view3d"'):dom.index('id="histogram"')]
    assert "plot-container plotly" in view and "gl-container" in view and "<canvas" in view
    assert "WebGL is not supported" not in dom
    hist = dom[dom.index('id="histogram"'):]
    assert "main-svg" in hist and 'class="point"' in hist
    assert ">FAIL<" in dom


def test_report_screenshot_is_not_blank(chromium, report, tmp_path):
    from matplotlib.image import imread

    shot = tmp_path / "shot.png"
    proc = _run(chromium, ["--window-size=1280,1800", f"--screenshot={shot}", report.as_uri()],
                tmp_path)
    assert proc.returncode == 0 and shot.exists(), proc.stderr[-2000:]
    img = imread(shot)[..., :3]
    assert img.shape[:2] == (1800, 1280)
    assert img.std() > 0.05
    # the verdict banner and the deviation colours of the 3D view are on screen
    px = (img.reshape(-1, 3) * 255).round()
    banner_red = np.all(np.abs(px - [0xB3, 0x26, 0x1E]) < 8, axis=1).sum()
    deep_blue = np.all(np.abs(px - [5, 48, 97]) < 40, axis=1).sum()
    assert banner_red > 5000 and deep_blue > 20
