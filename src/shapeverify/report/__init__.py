"""Reports people read: the self-contained HTML report, a PNG summary, a coloured PLY, and the
SQLite inspection history with trend charts.

All take an :class:`shapeverify.inspection.InspectionResult`; lengths are in mm everywhere.

Every writer comes twice: ``html_report``, ``png_summary``, ``colored_ply``, ``result_json``
return the file's bytes; ``write_*`` write them to a path.
"""

from .history import HistoryDB, control_limits, plot_trend
from .html import html_report, write_html_report
from .colours import deviation_colors
from .ply import colored_ply, write_colored_ply
from .png import png_summary, write_png_summary
from .result_json import result_json, write_result_json

__all__ = ["html_report", "write_html_report", "png_summary", "write_png_summary", "colored_ply",
           "write_colored_ply", "result_json", "write_result_json", "deviation_colors",
           "HistoryDB", "plot_trend", "control_limits"]
