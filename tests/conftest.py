"""Shared pytest fixtures.

``shared_data``: the folder of real CAD files and scans next to the project (``../shared/data``).
A fresh clone does not have it; tests that need it skip with a reason.
``example_step``: the bundled example part written to a temporary STEP file.
"""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session", autouse=True)
def _summary_cache(tmp_path_factory):
    """``info``'s summary cache (shapeverify.cad.summary) in a temporary folder, not the user's:
    no test writes to ~/.cache, and none sees entries of earlier runs.  No command a test starts
    goes to a resident worker (``SHAPEVERIFY_NO_WORKER=1``)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("SHAPEVERIFY_CACHE_DIR", str(tmp_path_factory.mktemp("summary-cache")))
    # the commands the tests start run in their own process, not in a resident worker the user
    # may have running (shapeverify worker start): a test of the worker sets its own
    mp.setenv("SHAPEVERIFY_NO_WORKER", "1")
    yield
    mp.undo()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ``../shared/data`` (relative to the repository root); skips when absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data not present (optional real CAD/scan files)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def example_step(tmp_path_factory) -> Path:
    """The example panel (300 x 200 mm B-spline sheet with a hole) written to STEP."""
    from shapeverify.cad.examples import example_part_step

    return example_part_step(tmp_path_factory.mktemp("example") / "panel.step")
