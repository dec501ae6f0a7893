"""Hostile scenario files and values: each refused with one located message (alias
bombs, deep nesting, self-referencing anchors, oversized, binary or non-UTF-8
files, devices), strict types, and run names that are safe file names."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cosim.errors import ScenarioError
from cosim.scenario.loader import load_scenario
from cosim.scenario.yaml_lines import (MAX_ALIAS_VALUES, MAX_DEPTH, MAX_FILE_BYTES, load_yaml,
                                       parse_scalar)

HEAD = "name: s\nduration: 1.0\ntick: 0.01\ncomponents:\n  a: {python: x:Y}\n"


def _refusal(tmp_path: Path, data: bytes | str) -> str:
    path = tmp_path / "s.yaml"
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    text = str(info.value)
    assert text.startswith(str(path)) and "\n" not in text
    return text.removeprefix(str(path))


def test_alias_bomb_is_refused_at_once(tmp_path):
    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 10)}]\n"
        for i in range(8))
    assert _refusal(tmp_path, HEAD + bomb) == (
        f":6: YAML refused: aliases expand to more than {MAX_ALIAS_VALUES} values "
        "(an alias bomb?)")


def test_aliases_within_the_limit_still_work():
    data, _, problems = load_yaml("a: &x {m: 1}\nb: [*x, *x]\nc: {<<: *x, n: 2}\n")
    assert problems == [] and data["b"] == [{"m": 1}, {"m": 1}] and data["c"] == {"m": 1, "n": 2}


@pytest.mark.parametrize("nested", ["[" * 5000 + "]" * 5000, "{a: " * 3000 + "1" + "}" * 3000])
def test_deep_nesting_is_refused(tmp_path, nested):
    assert _refusal(tmp_path, HEAD + "deep: " + nested + "\n") == (
        f":6: YAML refused: nesting deeper than {MAX_DEPTH} levels")


@pytest.mark.parametrize("text, message", [
    ("loop: &x [1, *x]\n", "an alias is used inside the value of its own anchor"),
    ("loop: &x {b: *x}\n", "an alias is used inside the value of its own anchor"),
    ("loop: &x {<<: *x, b: 1}\n", "a merge key (<<) refers to the mapping it is in"),
])
def test_self_referencing_anchors_are_refused(tmp_path, text, message):
    assert _refusal(tmp_path, HEAD + text) == f":6: YAML refused: {message}"


def test_nul_control_and_non_utf8_bytes_are_refused_with_their_line(tmp_path):
    assert _refusal(tmp_path, HEAD.encode() + b"b: \0\n") == (
        ":6: the file holds a NUL byte (not a text file?)")
    assert _refusal(tmp_path, HEAD + "b: \x07\n") == (
        ":6: YAML refused: the file holds the control character U+0007, which YAML does not "
        "allow (not a text file?)")
    assert _refusal(tmp_path, HEAD.encode() + b"b: caf\xe9\n") == (
        ":6: the file is not UTF-8 text (byte 0xe9 at line 6, column 7)")


def test_oversized_files_and_devices_are_refused_without_reading_them_whole(tmp_path):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as handle:
        handle.write(HEAD.encode() + b"#" * MAX_FILE_BYTES)
    for path in (big, Path("/dev/zero")):
        with pytest.raises(ScenarioError) as info:
            load_scenario(path)
        assert str(info.value) == (f"{path}: the file is larger than 10 MB, the limit of a "
                                   "scenario or deployment file")
    with pytest.raises(ScenarioError, match="this is a folder, not a file"):
        load_scenario(tmp_path)


def test_values_python_cannot_build_are_located(tmp_path):
    assert _refusal(tmp_path, HEAD + "description: 2024-13-45\n") == (
        ":6: description: cannot read value '2024-13-45': month must be in 1..12")
    with pytest.raises(yaml.YAMLError):
        parse_scalar("2024-13-45")


@pytest.mark.parametrize("field, value, shown", [
    ("duration", "true", "True"), ("tick", "true", "True"), ("duration", "'20'", "'20'"),
    ("start_time", "false", "False")])
def test_bools_and_strings_are_not_numbers(tmp_path, field, value, shown):
    text = HEAD.replace(f"{field}: 1.0", "").replace(f"{field}: 0.01", "") + f"{field}: {value}\n"
    assert _refusal(tmp_path, text).endswith(
        f": {field}: Input should be a valid number (got {shown})")


def test_integers_and_lists_of_pairs_still_read(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(HEAD.replace("duration: 1.0", "duration: 1")
                    + "metrics: {cones: [[1, 2.5]]}\n")
    scenario = load_scenario(path)
    assert scenario.total_ticks == 100 and scenario.metrics.cones == [(1.0, 2.5)]


@pytest.mark.parametrize("name", ["../../../X", "a/b", "a\\0b", "a" * 101, ".", "..", "a b",
                                  "caf\u00e9"])
def test_run_names_must_be_safe_file_names(tmp_path, name):
    text = HEAD.replace("name: s", f'name: "{name}"')
    assert ": name: must be a safe file name: letters, digits, '-', '_', '.' (at most 100 " \
           "characters, not . or ..)" in _refusal(tmp_path, text)


def test_override_of_the_name_is_refused_too(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(HEAD)
    with pytest.raises(ScenarioError, match=r"name: must be a safe file name.*set by --set"):
        load_scenario(path, ["name=../../../X"])
    assert load_scenario(path, ["name=run-1_a.b"]).name == "run-1_a.b"
