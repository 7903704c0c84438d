"""YAML read without trusting the file: bounded alias expansion, bounded nesting, every key's
line, and errors that name the file and line.

``yaml.safe_load`` is safe from code execution but not from a 600-byte file whose nested aliases
expand to a billion values ("billion laughs"), a recursive alias, nesting deep enough to exhaust
Python's stack, or a 5,000-digit integer (Python refuses to convert it with a bare
``ValueError``).  :func:`load_yaml` composes the node graph (aliases stay shared references
there, so composing is linear in the file) and builds the Python data itself, with

* an expansion budget: at most ``10 x`` the number of distinct nodes plus 1,000 values are
  built (a file without aliases is always within it; anchors used a few times are too);
* no recursive aliases, at most :data:`MAX_DEPTH` levels of nesting;
* keys that are plain scalars, each once per mapping; ``<<`` merge keys as YAML 1.1 defines them;
* scalars that Python cannot represent (huge integers, impossible dates) refused with their line.

Every problem raises :class:`YamlInputError` (a :class:`~shapeverify.errors.ShapeVerifyError` and
``ValueError``) whose message starts with the source name and the line.

>>> load_yaml("a: &x [1, 2]\\nb: *x\\n", "p.yaml")
{'a': [1, 2], 'b': [1, 2]}
>>> load_yaml("a: 1\\na: 2\\n", "p.yaml")
Traceback (most recent call last):
    ...
shapeverify.io.yaml_safe.YamlInputError: p.yaml, line 2: key 'a' appears twice in the same mapping (first on line 1); keep one
"""

from __future__ import annotations

import yaml

from shapeverify.errors import ShapeVerifyError

__all__ = ["YamlInputError", "load_yaml", "MAX_DEPTH"]

#: Deepest nesting of mappings and sequences accepted.
MAX_DEPTH = 100
_MERGE = "tag:yaml.org,2002:merge"
_COLLECTION_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq")
#: libyaml's composer when PyYAML has it: linear on nested flow collections (PyYAML's own
#: scanner takes seconds on ``[[[[...`` a few thousand deep) and with a nesting limit of its own
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class YamlInputError(ShapeVerifyError, ValueError):
    """A YAML text that cannot be read safely; ``line`` is 1-based or None."""

    def __init__(self, message: str, line: int | None = None):
        super().__init__(message)
        self.line = line


def load_yaml(text: str, source: str = "<yaml>", *, with_lines: bool = False):
    """The Python data of a YAML document (None for an empty one), built with the limits of the
    module docstring.

    Parameters
    ----------
    text : str
        The YAML document (one).
    source : str
        Stands for the text in error messages (the file name).
    with_lines : bool
        Also return ``{key path (tuple): 1-based line}`` for every mapping key and item.

    Returns
    -------
    data or (data, lines)

    Raises
    ------
    YamlInputError
        Syntax errors, more than one document, alias expansion beyond the budget, recursive
        aliases, nesting deeper than :data:`MAX_DEPTH`, non-scalar or repeated keys, scalars
        Python cannot represent.
    """
    try:
        node = yaml.compose(text, Loader=_LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        raise YamlInputError(f"{source}, line {line}: not valid YAML: "
                             f"{getattr(exc, 'problem', None) or exc}", line) from None
    except RecursionError:
        raise YamlInputError(f"{source}: the YAML is nested too deeply to read (more than "
                             f"{MAX_DEPTH} levels); the file is damaged or hostile") from None
    except ValueError as exc:  # e.g. a huge number in a directive
        raise YamlInputError(f"{source}: not valid YAML: {str(exc)[:200]}") from None
    lines: dict = {}
    data = None if node is None else _Builder(node, source, lines).build(node)
    return (data, lines) if with_lines else data


def _line(node) -> int:
    return node.start_mark.line + 1


class _Builder:
    """Builds plain Python data from a composed node graph, within the budget."""

    def __init__(self, root, source: str, lines: dict):
        self.source, self.lines = source, lines
        self.budget = 10 * _distinct_nodes(root) + 1000
        self.built = 0
        self.open: set = set()   # ids of the nodes being built (a recursive alias meets one)
        self.loader = yaml.SafeLoader("")

    def fail(self, node, text: str):
        raise YamlInputError(f"{self.source}, line {_line(node)}: {text}", _line(node))

    def build(self, node, path: tuple = (), depth: int = 0):
        self.lines.setdefault(path, _line(node))
        self.built += 1
        if self.built > self.budget:
            raise YamlInputError(
                f"{self.source}: the YAML's aliases (*name) expand to more than {self.budget} "
                "values (nested aliases, as in a 'billion laughs' file): refused; write the "
                "values out instead of aliases of aliases", _line(node))
        if isinstance(node, yaml.ScalarNode):
            return self.scalar(node)
        if depth >= MAX_DEPTH:
            self.fail(node, f"nested more than {MAX_DEPTH} levels deep; the file is damaged or "
                            "hostile")
        if id(node) in self.open:
            self.fail(node, "a recursive alias (an anchor used inside itself); write the "
                            "values out")
        if node.tag not in _COLLECTION_TAGS:   # !!binary {...}, !!python/..., !!set: refused
            self.fail(node, f"unsupported tag {node.tag!r} on a "
                            f"{'list' if isinstance(node, yaml.SequenceNode) else 'mapping'}")
        self.open.add(id(node))
        try:
            if isinstance(node, yaml.SequenceNode):
                return [self.build(v, path + (i,), depth + 1) for i, v in enumerate(node.value)]
            return self.mapping(node, path, depth)
        finally:
            self.open.discard(id(node))

    def mapping(self, node, path: tuple, depth: int) -> dict:
        out: dict = {}
        first: dict = {}
        merges = []
        for k, v in node.value:
            if isinstance(k, yaml.ScalarNode) and k.tag == _MERGE:
                merges.append(v)
                continue
            if not isinstance(k, yaml.ScalarNode):
                self.fail(k, "a key must be a plain name or number, not a list or mapping")
            key = self.scalar(k)
            try:
                seen = key in first
            except TypeError:
                self.fail(k, f"the key {k.value[:40]!r} cannot be used as a key")
            if seen:
                self.fail(k, f"key {key!r} appears twice in the same mapping (first on line "
                             f"{first[key]}); keep one")
            first[key] = _line(k)
            self.lines[path + (key,)] = _line(k)
            out[key] = self.build(v, path + (key,), depth + 1)
        for m in merges:   # YAML 1.1 merge keys: explicit keys win, then earlier merges
            items = m.value if isinstance(m, yaml.SequenceNode) else [m]
            for item in items:
                if not isinstance(item, yaml.MappingNode):
                    self.fail(item, "'<<' merges a mapping or a list of mappings")
                own, self.lines = self.lines, {}
                try:
                    merged = self.build(item, path, depth + 1)
                finally:
                    own, self.lines = self.lines, own
                for key, value in merged.items():
                    if key not in out:
                        out[key] = value
                        for p, ln in own.items():   # the lines of the merged keys
                            if p[:len(path) + 1] == path + (key,):
                                self.lines.setdefault(p, ln)
        return out

    def scalar(self, node):
        try:
            return self.loader.construct_object(node, deep=True)
        except (yaml.YAMLError, ValueError, OverflowError, TypeError) as exc:
            text = node.value if isinstance(node.value, str) else str(node.value)
            shown = text if len(text) <= 40 else f"{text[:20]}...({len(text)} characters)"
            why = getattr(exc, "problem", None) or str(exc)
            self.fail(node, f"the value {shown!r} cannot be read ({str(why)[:120]})")


def _distinct_nodes(root) -> int:
    """The number of distinct nodes of the graph (aliases counted once), without recursion."""
    seen, stack = set(), [root]
    while stack:
        n = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        if isinstance(n, yaml.SequenceNode):
            stack.extend(n.value)
        elif isinstance(n, yaml.MappingNode):
            for k, v in n.value:
                stack.append(k)
                stack.append(v)
    return len(seen)
