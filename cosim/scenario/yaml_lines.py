"""YAML loading that remembers where every value came from.

`load_yaml` turns YAML text into plain Python data (dicts, lists, scalars) and
a `LineMap` from each value's document path, e.g. ("components", "vehicle",
"period") or ("connections", 2), to its 1-based line, so that validation errors
can name the line. Duplicate keys, which plain YAML loading silently
overwrites, are reported as problems.

Scalars follow YAML 1.1 as PyYAML's safe loader reads them, plus exponent
floats without a dot ("1e-3"), which PyYAML would otherwise read as strings.

Hostile or broken documents get one located problem, never a crash: nesting
deeper than `MAX_DEPTH`, aliases that expand to more than `MAX_ALIAS_VALUES`
values (an "alias bomb"), an anchor used inside its own value, characters YAML
does not allow (NUL, other control characters) and scalars Python cannot
construct (an out-of-range date, an integer of thousands of digits, a tag
such as `!!python/object:...`), each on one line.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from cosim.errors import Problem

PathKey = tuple[str | int, ...]

MAX_FILE_BYTES = 10 * 1024 * 1024  # a scenario file is a few kB; tables stay far below this
MAX_DEPTH = 64  # nested mappings and lists; a scenario needs about 6
MAX_ALIAS_VALUES = 100_000  # values built again through aliases, over the whole document
YAML_TAG_PREFIX = "tag:yaml.org,2002:"  # what "!!" abbreviates


class YamlLimitError(yaml.YAMLError):
    """A document that breaks a limit of the loader, or that Python cannot construct.

    Attributes:
        problem: what is wrong (as for PyYAML's marked errors).
        line: 1-based line where it is, or None.
    """

    def __init__(self, problem: str, line: int | None) -> None:
        super().__init__(problem)
        self.problem, self.line = problem, line
        self.problem_mark = None


class _Loader(yaml.SafeLoader):
    """Safe loader that also reads "1e-3" and "2E+5" as floats, and bounds
    nesting and merge-key cycles (PyYAML itself recurses without a limit)."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._merging: set[int] = set()

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise YamlLimitError(f"nesting deeper than {MAX_DEPTH} levels",
                                     self.peek_event().start_mark.line + 1)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def flatten_mapping(self, node: Any) -> None:
        if id(node) in self._merging:
            raise YamlLimitError("a merge key (<<) refers to the mapping it is in",
                                 node.start_mark.line + 1)
        self._merging.add(id(node))
        try:
            super().flatten_mapping(node)  # calls this method again for merged mappings
        finally:
            self._merging.discard(id(node))


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

    def overrides_within(self, path: Sequence[str | int]) -> list[str]:
        """The override texts that set `path`, an ancestor of it or a field under it
        (a connection whose `delay` came from --set), in the order they were given."""
        key = tuple(path)
        return [text for where, text in self.detached.items()
                if where[:len(key)] == key or key[:len(where)] == where]

    def also_set(self, path: Sequence[str | int]) -> str:
        """" (tick set by --set tick=20)" when an override set `path`, else "": the note
        for a problem located at another field that `path`'s value entered into (a
        duration that is no whole number of ticks, where the tick came from --set)."""
        override = self.override_of(path)
        return f" ({format_path(path)} set by --set {override})" if override is not None else ""


def read_yaml_file(path: str | Path) -> str:
    """The text of a YAML file, refusing what cannot be a scenario.

    At most MAX_FILE_BYTES + 1 bytes are read, so a device (/dev/zero) or a huge
    file costs nothing; the text must be UTF-8 without NUL bytes.

    Args:
        path: the file.
    Raises:
        FileNotFoundError: when there is no such file.
        YamlLimitError: a folder, an unreadable, oversized, binary or non-UTF-8 file
            (with the line of the first bad byte).
    """
    try:
        with open(path, "rb") as handle:
            raw = handle.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise
    except IsADirectoryError:
        raise YamlLimitError("this is a folder, not a file", None) from None
    except OSError as exc:
        raise YamlLimitError(f"cannot read the file: {exc.strerror or exc}", None) from None
    if len(raw) > MAX_FILE_BYTES:
        raise YamlLimitError(f"the file is larger than {MAX_FILE_BYTES // 2**20} MB, "
                             "the limit of a scenario or deployment file", None)
    if b"\0" in raw:
        line = raw.count(b"\n", 0, raw.index(b"\0")) + 1
        raise YamlLimitError("the file holds a NUL byte (not a text file?)", line)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise YamlLimitError(f"the file is not UTF-8 text (byte 0x{raw[exc.start]:02x} at "
                             f"line {line}, column {column})", line) from None


def parse_scalar(text: str) -> Any:
    """Parse a command-line value as YAML ("2.0" -> 2.0, "[1, 2]" -> [1, 2], "abc" -> "abc").

    Args:
        text: the value text; an empty string gives None.
    Raises:
        yaml.YAMLError: when the text is not valid YAML or breaks a limit of the
            loader (YamlLimitError).
    """
    node = _compose(text)
    if node is None:
        return None
    problems: list[Problem] = []
    value = _Builder().build(node, (), LineMap(), problems)
    if problems:
        raise YamlLimitError(problems[0].message, problems[0].line)
    return value


def load_yaml(text: str) -> tuple[Any, LineMap, list[Problem]]:
    """Load YAML text into plain data plus the line of every value.

    Args:
        text: the YAML document.
    Returns:
        (data, line map, problems); problems holds syntax errors and broken
        limits (then data is None) and duplicate keys (the later value wins,
        as in plain YAML).
    """
    lines = LineMap()
    problems: list[Problem] = []
    try:
        node = _compose(text)
        if node is None:
            return None, lines, problems
        data = _Builder().build(node, (), lines, problems)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        message = str(exc.problem or exc.context or "invalid YAML")
        return None, LineMap(), [Problem("", line, f"YAML syntax error: {message}")]
    except YamlLimitError as exc:
        return None, LineMap(), [Problem("", exc.line, f"YAML refused: {exc.problem}")]
    except yaml.YAMLError as exc:
        return None, LineMap(), [Problem("", None, f"YAML error: {one_line(exc)}")]
    return data, lines, problems


def _compose(text: str) -> yaml.Node | None:
    """The document's node graph (aliases are shared nodes, not yet expanded)."""
    try:
        loader = _Loader(text)
    except yaml.reader.ReaderError as exc:  # the reader checks every character up front
        raise _reader_problem(text, exc) from None
    try:
        return loader.get_single_node()
    except yaml.reader.ReaderError as exc:
        raise _reader_problem(text, exc) from None
    finally:
        loader.dispose()


def _reader_problem(text: str, exc: yaml.reader.ReaderError) -> YamlLimitError:
    """A character YAML refuses (NUL, a control character) as a located problem."""
    char = exc.character  # a code point (int), or a byte for bytes input
    code = ord(char) if isinstance(char, str) else int(char)
    name = "a NUL byte" if code == 0 else f"the control character U+{code:04X}"
    return YamlLimitError(f"the file holds {name}, which YAML does not allow (not a text file?)",
                          text.count("\n", 0, exc.position) + 1)


def one_line(exc: BaseException) -> str:
    """An exception's text on one line: a PyYAML marked error without its
    'in "<unicode string>", line 1, column 1:' block and caret."""
    if isinstance(exc, yaml.MarkedYAMLError):
        text = " ".join(str(part) for part in (exc.context, exc.problem) if part) or type(exc).__name__
    else:
        text = str(exc)
    return " ".join(text.split())


def _constructor_problem(node: yaml.ScalarNode, exc: yaml.constructor.ConstructorError) -> str:
    """What is wrong with a scalar PyYAML's safe constructor refused: an unknown tag
    (shown as written, "!!python/object:os.system"), or PyYAML's reason on one line."""
    if "could not determine a constructor" in str(exc.problem):
        tag = str(node.tag)
        shown = "!!" + tag.removeprefix(YAML_TAG_PREFIX) if tag.startswith(YAML_TAG_PREFIX) else tag
        return (f"the tag {shown!r} is not supported (a scenario holds plain values: "
                "numbers, strings, true/false, lists, mappings)")
    return f"cannot read value {node.value[:40]!r}: {one_line(exc)}"


class _Builder:
    """Plain data from a composed node graph, with lines by path.

    Each alias is built again where it is used (as PyYAML does), so the number
    of values built through aliases is counted and bounded; an alias used
    inside the value of its own anchor is refused instead of recursing.
    """

    def __init__(self) -> None:
        self.constructor = _Loader("")
        self.seen: set[int] = set()      # nodes built at least once
        self.open: set[int] = set()      # nodes being built (the current path)
        self.repeats = 0                 # values built again through an alias

    def build(self, node: yaml.Node, path: PathKey, lines: LineMap,
              problems: list[Problem]) -> Any:
        """Construct plain data from `node` at document path `path`."""
        key = id(node)
        line = node.start_mark.line + 1
        if key in self.open:
            raise YamlLimitError("an alias is used inside the value of its own anchor", line)
        if key in self.seen:
            self.repeats += 1
            if self.repeats > MAX_ALIAS_VALUES:
                raise YamlLimitError(f"aliases expand to more than {MAX_ALIAS_VALUES} values "
                                     "(an alias bomb?)", line)
        self.seen.add(key)
        lines.lines.setdefault(path, line)
        if isinstance(node, yaml.ScalarNode):
            return self._scalar(node, path, problems)
        self.open.add(key)
        try:
            if isinstance(node, yaml.MappingNode):
                return self._mapping(node, path, lines, problems)
            return [self.build(item, path + (i,), lines, problems)
                    for i, item in enumerate(node.value)]
        finally:
            self.open.discard(key)

    def _scalar(self, node: yaml.ScalarNode, path: PathKey, problems: list[Problem]) -> Any:
        try:
            return self.constructor.construct_object(node, deep=True)
        except yaml.constructor.ConstructorError as exc:  # !!python/object:os.system, !foo
            problems.append(Problem(format_path(path), node.start_mark.line + 1,
                                    _constructor_problem(node, exc)))
            return None
        except (yaml.YAMLError, ValueError, OverflowError) as exc:  # 2024-13-45, 10**5000
            problems.append(Problem(format_path(path), node.start_mark.line + 1,
                                    f"cannot read value {node.value[:40]!r}: {one_line(exc)}"))
            return None

    def _mapping(self, node: yaml.MappingNode, path: PathKey, lines: LineMap,
                 problems: list[Problem]) -> dict[str, Any]:
        """A dict from a mapping node; reports duplicate and non-scalar keys.

        Keys are always strings: a key YAML reads as another type keeps its text.
        """
        explicit = {id(k) for k, _ in node.value if k.tag != "tag:yaml.org,2002:merge"}
        self.constructor.flatten_mapping(node)  # resolves "<<" merges: merged entries first
        result: dict[str, Any] = {}
        first_line: dict[str, int] = {}
        for key_node, value_node in node.value:
            line = key_node.start_mark.line + 1
            if not isinstance(key_node, yaml.ScalarNode):
                problems.append(Problem(format_path(path), line, "a key must be a plain value"))
                continue
            key = key_node.value  # keys are names: 1, true, null stay as written ("1", "true")
            if key in first_line and id(key_node) in explicit:
                problems.append(Problem(format_path(path + (key,)), line,
                                        f"duplicate key {key!r} (first at line {first_line[key]})"))
            if id(key_node) in explicit:
                first_line.setdefault(key, line)
            child = path + (key,)
            lines.lines[child] = line
            result[key] = self.build(value_node, child, lines, problems)
        return result
