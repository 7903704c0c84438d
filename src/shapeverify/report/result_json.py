"""The JSON of an inspection (what ``shapeverify inspect --json`` writes), as bytes or a file."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["result_json", "write_result_json"]


def result_json(result, *, timings: dict | None = None) -> bytes:
    """``result.to_dict()`` as indented JSON (ASCII bytes), with ``timings`` (seconds per stage
    of the front end, e.g. reading the files) added to the result's own.

    Example
    -------
    >>> from types import SimpleNamespace
    >>> r = SimpleNamespace(to_dict=lambda: {"verdict": "pass", "timings": {"total": 1.0}})
    >>> result_json(r, timings={"read_scan_s": 0.5}).decode().split()
    ['{', '"verdict":', '"pass",', '"timings":', '{', '"total":', '1.0,', '"read_scan_s":', '0.5', '}', '}']
    """
    payload = result.to_dict()
    if timings:
        payload["timings"] = {**payload.get("timings", {}), **timings}
    return json.dumps(payload, indent=2).encode("ascii")


def write_result_json(result, path, *, timings: dict | None = None) -> Path:
    """Write :func:`result_json` to ``path`` (str or Path); return it as a Path."""
    path = Path(path)
    path.write_bytes(result_json(result, timings=timings))
    return path
