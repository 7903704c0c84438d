"""Text on the terminal exactly as written: units in brackets are not Rich markup.

Rich reads ``[mm]``, ``[mm²]``, ``[s]`` (any lower-case word in brackets) as a style tag and
drops it, so option help, table titles, headers and cells lost their units (issue 32).  Every
table of the command line is a :class:`Table` (its strings are plain text; give a
:class:`rich.text.Text` for colour), and :func:`readable_help` escapes the help of every command
and option once, so a help string written with ``[mm]`` shows ``[mm]``.  Typer shows a flag's
type as ``<bool>``; :func:`readable_help` leaves flags without a type column entry.
"""

from __future__ import annotations

from rich.markup import escape
from rich.table import Table as _RichTable
from rich.text import Text

__all__ = ["Table", "plain", "readable_help"]


def plain(value):
    """``value`` as a renderable that shows its text as written (a str becomes a
    :class:`~rich.text.Text`; anything else is returned unchanged)."""
    return Text(value) if isinstance(value, str) else value


class Table(_RichTable):
    """A :class:`rich.table.Table` whose string title, headers and cells are plain text.

    Examples
    --------
    >>> from rich.console import Console
    >>> t = Table(title="Deviation [mm]")
    >>> _ = t.add_column("area [mm²]")
    >>> t.add_row("12.5")
    >>> c = Console(width=40, file=__import__("io").StringIO())
    >>> c.print(t)
    >>> "[mm]" in c.file.getvalue() and "[mm²]" in c.file.getvalue()
    True
    """

    def __init__(self, *headers, title=None, caption=None, **kwargs):
        super().__init__(*(plain(h) for h in headers), title=plain(title), caption=plain(caption),
                         **kwargs)

    def add_column(self, header="", *args, **kwargs):
        return super().add_column(plain(header), *args, **kwargs)

    def add_row(self, *cells, **kwargs):
        return super().add_row(*(plain(c) for c in cells), **kwargs)


def _escape_help(obj) -> None:
    for attr in ("help", "short_help", "epilog"):
        text = getattr(obj, attr, None)
        if isinstance(text, str):
            setattr(obj, attr, escape(text))


def readable_help(command) -> None:
    """Escape Rich markup in the help of ``command``, its parameters and its sub-commands
    (once: a command already done is skipped), and give flags no ``<bool>`` type entry.

    Typer renders help with Rich markup on (``rich_markup_mode="rich"``): without this,
    ``Model-point spacing [mm]`` shows as ``Model-point spacing``."""
    if getattr(command, "_shapeverify_readable", False):
        return
    command._shapeverify_readable = True
    _escape_help(command)
    for param in getattr(command, "params", ()):
        _escape_help(param)
        if getattr(param, "is_flag", False) and getattr(param, "metavar", None) is None:
            param.metavar = ""        # Typer shows a flag's type as "<bool>"; a flag has no value
    _hide_help_option_type(command)
    for sub in (getattr(command, "commands", None) or {}).values():
        readable_help(sub)


def _hide_help_option_type(command) -> None:
    """``--help`` is made on demand by the command (Typer's ``get_help_option``): wrap it so the
    option it makes has no ``<bool>`` type entry either."""
    make = getattr(command, "get_help_option", None)
    if make is None:
        return

    def get_help_option(ctx, _make=make):
        option = _make(ctx)
        if option is not None and getattr(option, "metavar", None) is None:
            option.metavar = ""
        return option

    command.get_help_option = get_help_option


def format_limits(lower, upper) -> str:
    """A characteristic's limits for the terminal's table: ``lower .. upper`` (4 decimals, a
    missing limit as ``–``); per entry, one a line, when the limits are dicts (a hole's
    diameter and position).

    >>> format_limits(-0.1, 0.1)
    '-0.1000 .. +0.1000'
    >>> print(format_limits({"diameter": 35.8, "position": 0.0}, {"diameter": 36.2, "position": 0.3}))
    diameter 35.8000 .. 36.2000
    position 0.0000 .. 0.3000
    """
    if isinstance(lower, dict) or isinstance(upper, dict):
        lower = lower if isinstance(lower, dict) else {}
        upper = upper if isinstance(upper, dict) else {}
        keys = list(dict.fromkeys([*lower, *upper]))
        return "\n".join(f"{k} {_number(lower.get(k))} .. {_number(upper.get(k))}" for k in keys)
    return f"{_number(lower, signed=True)} .. {_number(upper, signed=True)}"


def _number(v, signed: bool = False) -> str:
    if v is None or not isinstance(v, (int, float)) or isinstance(v, bool):
        return "–" if v is None else str(v)
    return f"{v:+.4f}" if signed else f"{v:.4f}"


def sig3(v: float) -> str:
    """A length or area with at least three significant digits, without an exponent for the
    sizes of parts: ``0.00123``, ``12.3``, ``1,234`` (never ``0.0`` for a small value).

    >>> [sig3(x) for x in (0.0012345, 0.5, 12.345, 1234.5, 0.0)]
    ['0.00123', '0.5', '12.3', '1,234', '0']
    """
    v = float(v)
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    return f"{v:.3g}"


def coordinates(values) -> str:
    """``values`` (a few floats) as ``np.array2string(np.round(values, 2) + 0.0, precision=2,
    suppress_small=True)`` writes them (``[  0.   200.    16.03]``), without importing numpy
    for ``shapeverify info`` of a cached summary (0.06-0.1 s of CPU; issue 32 item 7).  Values
    numpy would write otherwise (non-finite, >= 1e8: exponents) are written by numpy itself."""
    import math

    rounded = [float(round(float(v) * 100.0)) / 100.0 + 0.0 if math.isfinite(float(v))
               else float(v) for v in values]
    if not rounded or not all(math.isfinite(x) and abs(x) < 1e8 for x in rounded):
        import numpy as np

        return np.array2string(np.round(np.asarray(values, dtype=float), 2) + 0.0,
                               precision=2, suppress_small=True)
    parts = []
    for x in rounded:
        whole, frac = repr(x).split(".")       # positional: 0.01 <= |x| < 1e8, or 0
        parts.append((whole, frac.rstrip("0")))
    left = max(len(w) for w, _ in parts)
    right = max(len(f) for _, f in parts)
    return "[" + " ".join(f"{w.rjust(left)}.{f.ljust(right)}" for w, f in parts) + "]"
