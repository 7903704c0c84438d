"""No public function takes more than 10 parameters (issue 31, "How good").

65 public functions took 10 or more (KISS-ICP has 1; small_gicp passes one settings struct);
options travel grouped instead: :class:`~shapeverify.options.InspectionOptions`,
:class:`~shapeverify.registration.RegistrationOptions` and small frozen dataclasses such as
:class:`~shapeverify.simulate.ScanEffects` or :class:`~shapeverify.fitting.FitSolver`, whose
fields the old loose keywords still fill, with a DeprecationWarning
(:func:`shapeverify._renamed.grouped_keywords`).

The rule, read with :mod:`ast` from the sources (no import needed): a function is public when
no part of its module's path and not its own name starts with an underscore (``__init__.py``
counts as public); it counts its positional and keyword parameters (``self``/``cls`` of a
method, ``*args`` and ``**kwargs`` not).  Left out: numba kernels (decorated with ``njit``,
``jit`` or ``vectorize``) and the command functions of the command line (decorated with
``<app>.command(...)``: one parameter per option is what a command line is).  Run this file as
a script to print every public function with its count, largest first.
"""

from __future__ import annotations

import ast
import sys
import warnings
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "shapeverify"
LIMIT = 10
#: functions still over the limit, each with the reason; may only shrink
LEFT: set = set()


def _exempt(fn: ast.FunctionDef) -> bool:
    for d in fn.decorator_list:
        text = ast.unparse(d)
        head = text.split("(")[0]
        if head.split(".")[-1] in ("njit", "jit", "vectorize", "guvectorize"):
            return True
        if head.endswith(".command"):
            return True
    return False


def _count(fn: ast.FunctionDef, method: bool) -> int:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if method and names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names)


def public_functions(root: Path = PACKAGE) -> dict[str, int]:
    """``"path:qualname" -> number of parameters`` of every public function (the rule above)."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root)
        if any(part.startswith("_") and part not in ("__init__.py", "__main__.py")
               for part in rel.parts):
            continue

        def visit(body, prefix=""):
            for node in body:
                if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                    visit(node.body, prefix + node.name + ".")
                elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    if node.name.startswith("_") or _exempt(node):
                        continue
                    out[f"{rel.as_posix()}:{prefix}{node.name}"] = _count(node, bool(prefix))

        visit(ast.parse(p.read_text(), str(p)).body)
    return out


def test_no_public_function_takes_more_than_ten_parameters():
    over = {k: n for k, n in public_functions().items() if n > LIMIT and k not in LEFT}
    assert not over, ("public functions over %d parameters (group them into an options "
                      "object or a small frozen dataclass):\n" % LIMIT
                      + "\n".join(f"{n:3d} {k}" for k, n in sorted(over.items(),
                                                                    key=lambda kv: -kv[1])))


def test_the_left_list_only_names_functions_still_over_the_limit():
    counts = public_functions()
    stale = [k for k in LEFT if counts.get(k, 0) <= LIMIT]
    assert not stale, f"remove from LEFT (now within the limit or gone): {stale}"


def test_the_rule_sees_kernels_commands_and_methods(tmp_path):
    """The rule on a small package: a 12-parameter function counts, a jitted kernel, a
    command, a private module and a private function do not, ``self`` is not a parameter."""
    pkg = tmp_path / "pkg"
    (pkg / "_private").mkdir(parents=True)
    args = ", ".join(f"a{i}" for i in range(12))
    (pkg / "mod.py").write_text(
        f"import numba\n@numba.njit(cache=True)\ndef kernel({args}):\n    pass\n"
        f"@app.command()\ndef cmd({args}):\n    pass\n"
        f"def wide({args}):\n    pass\n"
        f"def _hidden({args}):\n    pass\n"
        "class C:\n"
        "    def m(self, " + ", ".join(f"b{i}" for i in range(10)) + "):\n        pass\n")
    (pkg / "_private" / "x.py").write_text(f"def wide({args}):\n    pass\n")
    assert public_functions(pkg) == {"mod.py:wide": 12, "mod.py:C.m": 10}


# ------------------------------------------------------------------ the grouped keywords
def test_old_loose_keywords_still_work_and_give_the_same_answer():
    """``virtual_scan(..., outlier_fraction=0.1)`` (now a field of ScanEffects) gives the scan
    of ``effects=ScanEffects(outlier_fraction=0.1)``, with a DeprecationWarning naming the
    new spelling; ``fit_curve(max_iterations=)`` likewise through FitSolver."""
    import numpy as np

    from shapeverify import fitting
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.simulate import ScanEffects, virtual_scan

    model = wavy_panel()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        new = virtual_scan(model, pixel=8.0, rng=4,
                           effects=ScanEffects(outlier_fraction=0.1, dents=[(0.3, 20.0)]))
    with pytest.warns(DeprecationWarning, match=r"virtual_scan\(outlier_fraction=, dents=\) "
                                                r"is now a field of ScanEffects, passed as "
                                                r"effects="):
        old = virtual_scan(model, pixel=8.0, rng=4, outlier_fraction=0.1, dents=[(0.3, 20.0)])
    assert np.array_equal(old.scan, new.scan) and np.array_equal(old.labels, new.labels)
    assert (old.labels != 0).any()          # the effects were applied, not dropped

    t = np.linspace(0.0, 1.0, 60)
    pts = np.c_[np.cos(3 * t), np.sin(3 * t), t]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        a = fitting.fit_curve(pts, n_ctrl=6, solver=fitting.FitSolver(max_iterations=3))
    with pytest.warns(DeprecationWarning, match="FitSolver"):
        b = fitting.fit_curve(pts, n_ctrl=6, max_iterations=3)
    assert np.array_equal(a.curve.control, b.curve.control) and a.iterations == b.iterations


if __name__ == "__main__":
    for k, n in sorted(public_functions().items(), key=lambda kv: (-kv[1], kv[0])):
        if n > LIMIT - 3 or "-v" in sys.argv:
            print(f"{n:3d} {k}" + ("  (left)" if k in LEFT else ""))
