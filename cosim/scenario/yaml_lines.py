"""YAML loading that remembers where every value came from.

`load_yaml` turns YAML text into plain Python data (dicts, lists, scalars) and
a `LineMap` from each value's document path, e.g. ("components", "vehicle",
"period") or ("connections", 2), to its 1-based line, so that validation errors
can name the line. Duplicate keys, which plain YAML loading silently
overwrites, are reported as problems.

Scalars follow YAML 1.1 as PyYAML's safe loader reads them, plus exponent
floats without a dot ("1e-3"), which PyYAML would otherwise read as strings.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml

from cosim.errors import Problem

PathKey = tuple[str | int, ...]


class _Loader(yaml.SafeLoader):
    """Safe loader that also reads "1e-3" and "2E+5" as floats."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def format_path(path: Sequence[str | int]) -> str:
    """Render a document path as text: ("connections", 2, "to") -> "connections[2].to"."""
    text = ""
    for key in path:
        if isinstance(key, int):
            text += f"[{key}]"
        else:
            text += f".{key}" if text else str(key)
    return text


@dataclass
class LineMap:
    """Lines of the values of one document, by document path.

    Attributes:
        lines: path -> 1-based line of the value (of the key, for mapping entries).
        detached: paths whose values did not come from the file (command-line
            overrides): their subtree has no line.
    """

    lines: dict[PathKey, int] = field(default_factory=dict)
    detached: dict[PathKey, str] = field(default_factory=dict)

    def line_of(self, path: Sequence[str | int]) -> int | None:
        """The line of `path`, or of its nearest ancestor in the file; None if overridden."""
        key = tuple(path)
        if self.override_of(key) is not None:
            return None
        while key:
            if key in self.lines:
                return self.lines[key]
            key = key[:-1]
        return self.lines.get((), None)

    def override_of(self, path: Sequence[str | int]) -> str | None:
        """The override text that set `path` or one of its ancestors, if any."""
        key = tuple(path)
        for depth in range(len(key), 0, -1):
            if key[:depth] in self.detached:
                return self.detached[key[:depth]]
        return None


def parse_scalar(text: str) -> Any:
    """Parse a command-line value as YAML ("2.0" -> 2.0, "[1, 2]" -> [1, 2], "abc" -> "abc").

    Args:
        text: the value text; an empty string gives None.
    Raises:
        yaml.YAMLError: when the text is not valid YAML.
    """
    return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader


def load_yaml(text: str) -> tuple[Any, LineMap, list[Problem]]:
    """Load YAML text into plain data plus the line of every value.

    Args:
        text: the YAML document.
    Returns:
        (data, line map, problems); problems holds syntax errors (then data is
        None) and duplicate keys (the later value wins, as in plain YAML).
    """
    lines = LineMap()
    problems: list[Problem] = []
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        message = str(exc.problem or exc.context or "invalid YAML")
        return None, lines, [Problem("", line, f"YAML syntax error: {message}")]
    except yaml.YAMLError as exc:
        return None, lines, [Problem("", None, f"YAML error: {exc}")]
    finally:
        loader.dispose()
    if node is None:
        return None, lines, problems
    data = _build(node, (), lines, problems, _Loader(""))
    return data, lines, problems


def _build(node: yaml.Node, path: PathKey, lines: LineMap,
           problems: list[Problem], loader: _Loader) -> Any:
    """Construct plain data from a composed node, recording lines by path."""
    lines.lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        return _build_mapping(node, path, lines, problems, loader)
    if isinstance(node, yaml.SequenceNode):
        return [_build(item, path + (i,), lines, problems, loader)
                for i, item in enumerate(node.value)]
    try:
        return loader.construct_object(node, deep=True)
    except yaml.YAMLError as exc:
        problems.append(Problem(format_path(path), node.start_mark.line + 1,
                                f"cannot read value: {exc}"))
        return None


def _build_mapping(node: yaml.MappingNode, path: PathKey, lines: LineMap,
                   problems: list[Problem], loader: _Loader) -> dict[str, Any]:
    """Construct a dict from a mapping node; report duplicate and non-scalar keys.

    Keys are always strings: a key YAML reads as another type keeps its text.
    """
    explicit = {id(k) for k, _ in node.value if k.tag != "tag:yaml.org,2002:merge"}
    loader.flatten_mapping(node)  # resolves "<<" merge keys: merged entries come first
    result: dict[str, Any] = {}
    first_line: dict[str, int] = {}
    for key_node, value_node in node.value:
        line = key_node.start_mark.line + 1
        if not isinstance(key_node, yaml.ScalarNode):
            problems.append(Problem(format_path(path), line, "a key must be a plain value"))
            continue
        key = loader.construct_object(key_node)
        if not isinstance(key, str):
            key = key_node.value  # keys are names: 1, true, null stay as written ("1", "true")
        if key in first_line and id(key_node) in explicit:
            problems.append(Problem(format_path(path + (str(key),)), line,
                                    f"duplicate key {key!r} (first at line {first_line[key]})"))
        if id(key_node) in explicit:
            first_line.setdefault(key, line)
        child = path + (key,)
        lines.lines[child] = line
        result[key] = _build(value_node, child, lines, problems, loader)
    return result
