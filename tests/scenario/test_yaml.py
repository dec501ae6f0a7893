"""Tests of cosim.scenario.yaml_lines: values with their lines, duplicates, merges, scalars."""

from __future__ import annotations

import pytest
import yaml

from cosim.errors import Problem
from cosim.scenario.yaml_lines import LineMap, format_path, load_yaml, parse_scalar

DOC = """\
name: demo
components:
  vehicle:
    fmu: Bicycle
    parameters:
      m: 1500
connections:
  - a -> b
  - from: c.x
    to: d.x
"""


def test_values_and_lines_by_path() -> None:
    data, lines, problems = load_yaml(DOC)
    assert problems == []
    assert data == {"name": "demo",
                    "components": {"vehicle": {"fmu": "Bicycle", "parameters": {"m": 1500}}},
                    "connections": ["a -> b", {"from": "c.x", "to": "d.x"}]}
    assert lines.lines[()] == 1
    assert [lines.line_of(p) for p in [("name",), ("components",), ("components", "vehicle"),
                                       ("components", "vehicle", "parameters", "m"),
                                       ("connections", 0), ("connections", 1),
                                       ("connections", 1, "to")]] == [1, 2, 3, 6, 8, 9, 10]


def test_missing_paths_fall_back_to_the_nearest_ancestor() -> None:
    _, lines, _ = load_yaml(DOC)
    assert lines.line_of(("components", "vehicle", "period")) == 3
    assert lines.line_of(("connections", 7, "delay")) == 7
    assert lines.line_of(("nothing",)) == 1


def test_overridden_paths_have_no_line() -> None:
    _, lines, _ = load_yaml(DOC)
    lines.detached[("components", "vehicle")] = "components.vehicle.fmu=x.fmu"
    assert lines.line_of(("components", "vehicle", "fmu")) is None
    assert lines.override_of(("components", "vehicle", "fmu")) == "components.vehicle.fmu=x.fmu"
    assert lines.override_of(("components",)) is None
    assert lines.line_of(("components",)) == 2
    assert LineMap().line_of(("a",)) is None


def test_duplicate_keys_are_problems_and_the_last_value_wins() -> None:
    data, _, problems = load_yaml("a: 1\nb:\n  c: 2\n  c: 3\na: 4\n")
    assert data == {"a": 4, "b": {"c": 3}}
    assert problems == [Problem("b.c", 4, "duplicate key 'c' (first at line 3)"),
                        Problem("a", 5, "duplicate key 'a' (first at line 1)")]


def test_syntax_error_has_a_line_and_no_data() -> None:
    data, _, problems = load_yaml("a: 1\nb: [1, 2\nc: 3\n")
    assert data is None
    assert len(problems) == 1 and problems[0].line == 3
    assert problems[0].message.startswith("YAML syntax error: expected ',' or ']'")


def test_non_scalar_key_is_a_problem() -> None:
    _, _, problems = load_yaml("? [a, b]\n: 1\n")
    assert problems == [Problem("", 1, "a key must be a plain value")]


def test_merge_keys_and_anchors() -> None:
    data, lines, problems = load_yaml("base: &b {m: 1, n: 2}\nv:\n  <<: *b\n  n: 5\n  n: 6\n")
    # a merged key may be overridden once; only an explicit repeat is a duplicate
    assert problems == [Problem("v.n", 5, "duplicate key 'n' (first at line 4)")]
    assert data["v"] == {"m": 1, "n": 6}
    assert lines.line_of(("v", "n")) == 5


def test_scalars_including_exponent_floats() -> None:
    data, _, _ = load_yaml("a: 1e-3\nb: 2E+5\nc: -3e2\nd: 1.5\ne: 7\nf: 'x'\ng: true\nh: e5\n")
    assert data == {"a": 0.001, "b": 200000.0, "c": -300.0, "d": 1.5, "e": 7, "f": "x",
                    "g": True, "h": "e5"}
    assert type(data["e"]) is int
    assert [parse_scalar(t) for t in ("2.0", "[1, 2]", "abc", "", "1e3", "{a: 1}")] == [
        2.0, [1, 2], "abc", None, 1000.0, {"a": 1}]
    with pytest.raises(yaml.YAMLError):
        parse_scalar("[1")


def test_format_path() -> None:
    assert format_path(("connections", 2, "to")) == "connections[2].to"
    assert format_path(("components", "vehicle", "period")) == "components.vehicle.period"
    assert format_path(()) == ""


def test_keys_are_kept_as_written_text() -> None:
    data, lines, problems = load_yaml("1: a\ntrue: b\nnull: c\n1.5: d\n")
    assert problems == []  # 1 and true would collide as Python keys (True == 1)
    assert data == {"1": "a", "true": "b", "null": "c", "1.5": "d"}
    assert lines.line_of(("true",)) == 2
