"""Convert the command line's option values without pydantic when the answer is plain.

typer >= 0.2x converts every parameter of the invoked command through a pydantic ``TypeAdapter``
(``typer._coercion.build_runtime_param``): importing pydantic and building ~20 adapters costs
0.15-0.3 s of CPU per command (issue 32 item 7; ``python -X importtime``: ``typer._adapters``
0.25 s), more than ``shapeverify info`` of a cached file may take in all.  Our commands use
only ``str``, ``bool``, ``int``, ``float``, ``Path`` and lists of them, without typer's range, parser or
path-check settings.  :func:`install` makes typer's parameters convert those values the way
pydantic's lax mode does (``"0.2"`` -> ``0.2``, ``"panel.svm"`` -> ``Path("panel.svm")``)
and hand every other value -- anything that is not a plain decimal number, an empty path,
any parameter with extra settings -- to typer's own pydantic conversion, unchanged; so a bad
value gets typer's own message (``tests/test_cli_params.py`` compares both on many values).

With a typer whose private layout differs (``typer.core.build_runtime_param``,
``typer._coercion.RuntimeParam``, ``typer._param_types.coerce_cli_path``), nothing is
changed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_args, get_origin

__all__ = ["install", "fast_value", "Decline"]

# decimal numbers whose conversion by float()/int() equals pydantic's lax str -> number
_FLOAT = re.compile(r"-?(?:0|[1-9][0-9]{0,17})(?:\.[0-9]{1,17})?(?:[eE][+-]?[0-9]{1,3})?\Z")
_INT = re.compile(r"-?(?:0|[1-9][0-9]{0,17})\Z")


class Decline(Exception):
    """The value is not plain: typer's own (pydantic) conversion decides."""


def _plain_info(info) -> bool:
    """No setting of typer's that changes a conversion (range, clamp, parser, path checks)."""
    return (getattr(info, "parser", None) is None and getattr(info, "min", None) is None
            and getattr(info, "max", None) is None and not getattr(info, "clamp", False)
            and getattr(info, "click_type", None) is None
            and getattr(info, "path_type", None) is None
            and not getattr(info, "resolve_path", False)
            and not getattr(info, "allow_dash", False)
            and not getattr(info, "exists", False))


def fast_value(annotation: Any, value: Any, coerce_path=None) -> Any:
    """``value`` converted to ``annotation`` (str, bool, int, float, Path or a list of one of them)
    as typer's pydantic adapter converts it; raises :class:`Decline` for anything else.
    ``coerce_path(path)``: typer's path checks on a ``Path`` (default: none)."""
    if get_origin(annotation) is list:
        args = get_args(annotation)
        if len(args) != 1 or not isinstance(value, (list, tuple)):
            raise Decline
        return [fast_value(args[0], v, coerce_path) for v in value]
    if annotation is str:
        if type(value) is str:
            return value
    elif annotation is bool:
        if type(value) is bool:
            return value
    elif annotation is float:
        if type(value) is str and _FLOAT.match(value):
            return float(value)
        if type(value) is float:
            return value
    elif annotation is int:
        if type(value) is str and _INT.match(value):
            return int(value)
        if type(value) is int:
            return value
    elif annotation is Path:
        if type(value) is str and value and value.strip() == value and "\0" not in value:
            path = Path(value)
            return coerce_path(path) if coerce_path is not None else path
        if isinstance(value, Path):
            return coerce_path(value) if coerce_path is not None else value
    raise Decline


def install() -> bool:
    """Make typer's parameters convert plain values without pydantic (see the module); True
    when installed (or already), False when this typer's layout is not the one known."""
    try:
        import typer.core as core
        from typer._coercion import RuntimeParam
        from typer._param_types import coerce_cli_path
    except ImportError:
        return False
    original = getattr(core, "build_runtime_param", None)
    if original is None or not hasattr(core, "_TyperParameter"):
        return False
    if getattr(original, "_shapeverify_fast", False):
        return True

    @dataclass(frozen=True)
    class PlainRuntimeParam(RuntimeParam):
        """typer's conversion for a plain value, its pydantic one for any other."""

        descriptor: Any
        slow: list

        def _coerce_value(self, value: Any, param, ctx) -> Any:
            info = self.parameter_info

            def checked(path):
                return coerce_cli_path(path, info, path_type=Path, param=param, ctx=ctx)

            try:
                return fast_value(self.annotation, value, checked)
            except Decline:
                if not self.slow:
                    self.slow.append(original(self.descriptor))
                return self.slow[0]._coerce_value(value, param=param, ctx=ctx)

    def build_runtime_param(descriptor):
        leaf = descriptor.annotation
        if get_origin(leaf) is list and len(get_args(leaf)) == 1:
            leaf = get_args(leaf)[0]
        if (descriptor.file_annotation is None and leaf in (str, bool, int, float, Path)
                and _plain_info(descriptor.parameter_info)):
            return PlainRuntimeParam(parameter_info=descriptor.parameter_info,
                                     annotation=descriptor.annotation, descriptor=descriptor,
                                     slow=[])
        return original(descriptor)

    build_runtime_param._shapeverify_fast = True
    build_runtime_param.original = original
    core.build_runtime_param = build_runtime_param
    return True
