"""Reports people read: the self-contained HTML report, a PNG summary, a coloured PLY, and the
SQLite inspection history with trend charts.

All take an :class:`shapeverify.inspection.InspectionResult`; lengths are in mm everywhere.

Every writer comes twice: ``html_report``, ``png_summary``, ``colored_ply``, ``result_json``
return the file's bytes; ``write_*`` write them to a path.

The names are imported on first use: writing the JSON result (``shapeverify inspect --json``)
does not import the HTML report's plotting, the characteristics or scipy.optimize (0.3-0.6 s
of CPU; issue 32 item 7).
"""

from __future__ import annotations

import importlib

# public name -> its module in this package
_PUBLIC = {
    "HistoryDB": "history", "control_limits": "history", "plot_trend": "history",
    "html_report": "html", "write_html_report": "html",
    "deviation_colors": "colours",
    "colored_ply": "ply", "write_colored_ply": "ply",
    "png_summary": "png", "write_png_summary": "png",
    "result_json": "result_json", "write_result_json": "result_json",
}

__all__ = ["html_report", "write_html_report", "png_summary", "write_png_summary", "colored_ply",
           "write_colored_ply", "result_json", "write_result_json", "deviation_colors",
           "HistoryDB", "plot_trend", "control_limits"]


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
