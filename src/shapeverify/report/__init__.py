"""Reports people read: the self-contained HTML report, a PNG summary, a coloured PLY, and the
SQLite inspection history with trend charts.

All take an :class:`shapeverify.inspection.InspectionResult`; lengths are in mm everywhere.
"""

from .history import HistoryDB, control_limits, plot_trend
from .html import write_html_report
from .ply import deviation_colors, write_colored_ply
from .png import write_png_summary

__all__ = ["write_html_report", "write_png_summary", "write_colored_ply", "deviation_colors",
           "HistoryDB", "plot_trend", "control_limits"]
