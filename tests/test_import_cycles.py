"""No import cycles between modules of different folders (issue 31 item 5), deferred or not,
and none through the packages' ``__init__`` re-exports.

:func:`import_graph` reads every module of the package with :mod:`ast` and links it to every
module it imports -- at the top or deferred inside a function, the same for a cycle --
(``from .x import y`` links to the module ``x.y`` when there is one, and to ``x``: a
package's ``__init__`` when ``x`` is one; a package's ``__init__`` links to every module it
re-exports).  ``import_graph(parents=True)`` also links each import to the packages Python runs
on the way (``from ..inspection.checks import f`` runs ``inspection/__init__`` and with it
everything that re-exports): the cycles through a package's re-exports;
:func:`cross_folder_cycles` lists the strongly connected components that hold modules of more
than one folder (the package's top-level modules count as the folder ``.``), each as one
shortest cycle through it.

Neither graph has a cycle between folders.  The last one through the packages' runs
(characteristics.evaluate -> ``inspection/__init__`` -> inspection.inspect -> characteristics)
was broken by moving the building blocks the characteristics evaluate on -- the tolerance, the
scan checks, the deviation reason codes, the spacing helpers and the grid kernels -- out of the
``inspection`` package into the leaf package ``shapeverify.measures``; their old import paths
re-export them (:func:`test_the_moved_names_keep_their_old_import_paths`).  Run this file as a
script to print the cycles inside one folder: ``python tests/test_import_cycles.py``.
"""

from __future__ import annotations

import ast
import functools
from collections import deque
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "shapeverify"



def _modules(root: Path = PACKAGE) -> dict[str, Path]:
    out = {}
    for p in root.rglob("*.py"):
        rel = p.relative_to(root).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _resolve(module: str, is_pkg: bool, level: int, target: str | None) -> str:
    base = module.split(".") if module else []
    if not is_pkg:
        base = base[:-1]
    if level > 1:
        base = base[:len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def import_graph(root: Path = PACKAGE, parents: bool = False) -> dict[str, set[str]]:
    """module -> the package modules it imports (top-level or deferred).

    ``parents``: also link to the packages whose ``__init__`` Python runs on the way
    (``import a.b.c`` runs ``a`` and ``a.b``): cycles through a package's re-exports.

    Built once per root, ``parents`` and state of its files (path, size, mtime) in a test run:
    every caller gets its own copy.
    """
    stamp = tuple(sorted((str(p), p.stat().st_size, p.stat().st_mtime_ns)
                         for p in Path(root).rglob("*.py")))
    return {m: set(t) for m, t in _import_graph(Path(root), parents, stamp).items()}


@functools.lru_cache(maxsize=8)
def _import_graph(root: Path, parents: bool, stamp: tuple) -> dict[str, frozenset[str]]:
    mods = _modules(root)
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, path in mods.items():
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = _resolve(m, is_pkg, node.level, node.module)
                else:
                    base = node.module or ""
                names = [f"{base}.{a.name}" if base else a.name for a in node.names] + [base]
            for n in names:
                if n.startswith("shapeverify."):
                    n = n[len("shapeverify."):]
                elif n == "shapeverify":
                    n = ""
                elif node.__class__ is ast.Import or not getattr(node, "level", 0):
                    continue
                # importing a.b.c imports the packages a and a.b first (with ``parents``); a
                # module's own packages are imported before it: no edge back to them
                parts = n.split(".")
                for k in range(1 if parents else len(parts), len(parts) + 1):
                    t = ".".join(parts[:k])
                    if t in mods and t != m and not (m + ".").startswith(t + "."):
                        graph[m].add(t)
    return {m: frozenset(t) for m, t in graph.items()}


_PACKAGES = {m for m, p in _modules().items() if p.name == "__init__.py"}


def folder(module: str) -> str:
    """The folder of a module: its top-level package (``.`` for the package's own modules)."""
    parts = module.split(".")
    return parts[0] if len(parts) > 1 or module in _PACKAGES else "."


def _sccs(graph):
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        work = [(v, iter(sorted(graph[v])))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        while work:
            node, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    out.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def cross_folder_cycles(graph=None) -> list[list[str]]:
    """One shortest cycle per pair of folders joined by a cycle, as a module list."""
    graph = import_graph() if graph is None else graph
    out = []
    for comp in _sccs(graph):
        if len(comp) < 2 or len({folder(m) for m in comp}) < 2:
            continue
        seen = set()
        for m in sorted(comp):
            for w in sorted(graph[m] & set(comp)):
                pair = tuple(sorted((folder(m), folder(w))))
                if pair[0] == pair[1] or pair in seen:
                    continue
                # a cycle through the edge m -> w
                sub = _path(graph, set(comp), w, m)
                if sub is not None:
                    seen.add(pair)
                    out.append([m] + sub)
    return out


def _path(graph, comp, a, b):
    prev = {a: None}
    q = deque([a])
    while q:
        v = q.popleft()
        if v == b:
            break
        for w in sorted(graph[v] & comp):
            if w not in prev:
                prev[w] = v
                q.append(w)
    if b not in prev:
        return None
    path, v = [], b
    while v is not None:
        path.append(v)
        v = prev[v]
    return path[::-1]


def test_no_cycle_between_folders():
    bad = cross_folder_cycles()
    assert not bad, "import cycles between folders:\n" + "\n".join(" -> ".join(c) for c in bad)


def cross_folder_components(graph) -> list[set[str]]:
    """The strongly connected components that hold modules of more than one folder."""
    return [set(c) for c in _sccs(graph) if len(c) > 1 and len({folder(m) for m in c}) > 1]


def test_no_cycle_between_folders_through_package_reexports():
    """No cross-folder cycle in the graph with the packages' runs either (camera <-> phase <->
    simulate were broken: the fringe analysis moved to ``camera.fringe_analysis``, the optical
    demo to ``simulate.stereo_demo``; characteristics <-> inspection <-> options: the
    characteristics' building blocks moved to ``measures``)."""
    g = import_graph(parents=True)
    assert not cross_folder_components(g), (
        "import cycles between folders through package __init__ re-exports:\n"
        + "\n".join(" -> ".join(c) for c in cross_folder_cycles(g)))


def test_the_shared_measures_are_a_leaf_package():
    """``measures`` (what the inspection and the characteristics share) reaches neither of them,
    with or without the packages' runs: the cycle cannot come back through it."""
    g = import_graph(parents=True)
    seen, todo = set(), [m for m in g if m == "measures" or m.startswith("measures.")]
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(g[m])
    assert not {folder(m) for m in seen} & {"inspection", "characteristics", "registration"}, \
        sorted(seen)


#: "old module:name  new module:name" (under shapeverify): the name moved to the leaf package
#: ``measures`` and the old path gives the very same object
MOVED = [
    "inspection:Tolerance measures.tolerance:Tolerance",
    "inspection.verdict:Tolerance measures.tolerance:Tolerance",
    "inspection:check_scan measures.checks:check_scan",
    "inspection:default_evaluation_distance measures.checks:default_evaluation_distance",
    "inspection.checks:check_scan measures.checks:check_scan",
    "inspection.checks:default_evaluation_distance measures.checks:default_evaluation_distance",
    "inspection.checks:MIN_SCAN_POINTS measures.checks:MIN_SCAN_POINTS",
    "inspection.checks:MAX_COPY_FRACTION measures.checks:MAX_COPY_FRACTION",
    "inspection.inspect:check_scan measures.checks:check_scan",
    "inspection.inspect:default_evaluation_distance measures.checks:default_evaluation_distance",
    "inspection.inspect:MIN_SCAN_POINTS measures.checks:MIN_SCAN_POINTS",
    "inspection:EVALUATED measures.codes:EVALUATED",
    "inspection:TOO_FAR measures.codes:TOO_FAR",
    "inspection:ON_BOUNDARY measures.codes:ON_BOUNDARY",
    "inspection:OUTSIDE_FACES measures.codes:OUTSIDE_FACES",
    "inspection.deviations:REASON_NAMES measures.codes:REASON_NAMES",
    "inspection.regions:median_spacing measures.spacing:median_spacing",
    "inspection.regions:nearest_distances measures.spacing:nearest_distances",
    "inspection.regions:neighbourhood_median measures.spacing:neighbourhood_median",
    "inspection.regions:_nanmedian_rows measures.spacing:nanmedian_rows",
    "inspection.region_measures:nanmedian_rows measures.spacing:nanmedian_rows",
    "inspection._grid_kernels:any_within measures._grid_kernels:any_within",
    "inspection._grid_kernels:mark_within measures._grid_kernels:mark_within",
    "inspection._grid_kernels:kernel_sums measures._grid_kernels:kernel_sums",
    "inspection._grid_kernels:nearest_other measures._grid_kernels:nearest_other",
    "inspection._grid_kernels:kernel_array measures._grid_kernels:kernel_array",
]


@pytest.mark.parametrize("row", MOVED)
def test_the_moved_names_keep_their_old_import_paths(row):
    import importlib
    import inspect

    (old, old_name), (new, new_name) = (x.split(":") for x in row.split())
    obj = getattr(importlib.import_module(f"shapeverify.{old}"), old_name)
    assert obj is getattr(importlib.import_module(f"shapeverify.{new}"), new_name), row
    if inspect.isclass(obj) or inspect.isfunction(obj):
        assert obj.__module__ == f"shapeverify.{new}", obj


def test_a_tolerance_from_the_old_path_is_the_same_class():
    """Objects built through the old path are instances of the one class (isinstance checks in
    the inspection, the service and the characteristics keep working)."""
    from shapeverify.inspection import Tolerance as Old
    from shapeverify.inspection.checks import default_evaluation_distance
    from shapeverify.measures.tolerance import Tolerance

    t = Old.symmetric(0.2)
    assert isinstance(t, Tolerance) and t == Tolerance(-0.2, 0.2)
    assert default_evaluation_distance(t) == default_evaluation_distance(0.2) == 1.0


def test_the_graph_sees_deferred_imports_and_reexports():
    """A deferred import counts (a function-level ``from .x import y``), a package's
    re-export is an edge from the package, and with ``parents`` an import of a submodule is an
    edge to its package."""
    g = import_graph()
    # inspection.inspect imports registration inside inspect() (deferred)
    assert "registration" in g["inspection.inspect"] or any(
        m.startswith("registration") for m in g["inspection.inspect"])
    assert "camera.stereo" in g["camera"]                      # camera/__init__ re-exports it
    gp = import_graph(parents=True)
    assert "phase" in gp["simulate.hologram"]                  # from ..phase.hologram import
    assert "phase" not in g["simulate.hologram"]


def test_a_cycle_through_a_package_init_is_found(tmp_path):
    """Two folders whose packages re-export modules that import each other's submodules: no
    cycle without the packages' runs, one with them."""
    for name, other in (("a", "b"), ("b", "a")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(f"from .m import f_{name}\n")
        (tmp_path / name / "m.py").write_text(
            f"def f_{name}():\n    from ..{other}.leaf import g\n    return g\n")
        (tmp_path / name / "leaf.py").write_text("def g():\n    return 1\n")
    (tmp_path / "__init__.py").write_text("")
    assert cross_folder_cycles(import_graph(tmp_path)) == []
    cyc = cross_folder_cycles(import_graph(tmp_path, parents=True))
    assert cyc and all({"a", "b", "a.m", "b.m"} == set(c) for c in cyc), cyc


def within_folder_cycles(graph=None) -> list[list[str]]:
    """The strongly connected components inside one folder (not checked: listed for the
    record; e.g. registration's helpers and global_search, cli.py and the cli_* modules)."""
    graph = import_graph() if graph is None else graph
    return [sorted(c) for c in _sccs(graph)
            if len(c) > 1 and len({folder(m) for m in c}) == 1]


if __name__ == "__main__":
    for c in cross_folder_cycles():
        print(" -> ".join(c))
    for c in within_folder_cycles():
        print("(within one folder) " + ", ".join(c))
    for c in cross_folder_cycles(import_graph(parents=True)):
        print("(through package __init__ re-exports) " + " -> ".join(c))
