"""Quiet set-up (issue 32, item 1): ``make test`` installed Chromium and chromium-driver (117
Debian packages, 15 upgrades of systemd, perl, ...) as root from inside pytest, printing
nothing.  Now the Makefile's ``browser`` target says what it installs before it installs only
``chromium`` (``--no-install-recommends``: 25 packages, no upgrade), pytest never installs, and
the browser test skips with the reason when Chromium is missing."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _recipe(target: str) -> str:
    text = (ROOT / "Makefile").read_text()
    m = re.search(rf"^{re.escape(target)}:.*\n((?:\t.*\n)+)", text, re.M)
    assert m, target
    return m.group(1)


def test_make_browser_says_what_it_installs_before_it_installs_only_chromium():
    recipe = _recipe("browser")
    install = recipe.index("apt-get install")
    said = recipe.index("installing Chromium for the browser test")
    assert said < install
    line = recipe[install:recipe.index("\n", install)]
    assert "--no-install-recommends" in line and "--no-upgrade" in line
    assert "chromium-driver" not in recipe and " chromium" in line
    assert "SKIP_BROWSER" in recipe and "will be skipped" in recipe     # refused or offline
    # `make test` runs it first, so the install is said on the terminal, not inside pytest
    assert "browser" in re.search(r"^test:(.*)$", (ROOT / "Makefile").read_text(), re.M).group(1)


def test_make_test_fast_selects_the_quick_tests():
    assert '-m "not slow and not shared"' in _recipe("test-fast")


def test_the_browser_test_never_installs_anything():
    src = (ROOT / "tests" / "test_report_browser.py").read_text()
    calls = re.findall(r"subprocess\.run\(\[([^\]]*)", src)
    assert not any("apt-get" in c for c in calls)
    assert "pytest.skip(" in src and "make browser" in src


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_make_browser_with_skip_browser_installs_nothing_and_says_so():
    proc = subprocess.run(["make", "-s", "browser", "SKIP_BROWSER=1"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    # Chromium already there: its path; else the note that the test will be skipped
    assert ("will be skipped" in proc.stdout) or ("Chromium for the browser test:" in proc.stdout)
    assert "installing Chromium" not in proc.stdout
