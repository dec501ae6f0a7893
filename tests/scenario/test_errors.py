"""Every class of bad scenario input gives a message with file, line, path and value."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.errors import Problem, ScenarioError, UserError
from cosim.scenario.loader import load_scenario

GOOD_HEAD = "name: s\nduration: 1\ntick: 0.01\ncomponents:\n"   # components start at line 5


def problems(tmp_path: Path, text: str, overrides: tuple[str, ...] = ()) -> list[str]:
    """The lines of the ScenarioError for a file, with the file name stripped."""
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    assert isinstance(info.value, UserError)
    text = str(info.value)
    assert text.count(str(path)) == len(info.value.problems)
    return [line.removeprefix(str(path)) for line in text.splitlines()]


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError) as info:
        load_scenario(tmp_path / "nope.yaml")
    assert str(info.value) == f"{tmp_path / 'nope.yaml'}: scenario file not found"


def test_undecodable_file(tmp_path: Path) -> None:
    path = tmp_path / "latin.yaml"
    path.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert str(info.value) == (f"{path}:1: the file is not UTF-8 text "
                               "(byte 0xe9 at line 1, column 10)")


def test_numeric_component_name(tmp_path: Path) -> None:
    assert problems(tmp_path, GOOD_HEAD + "  1: {python: x:Y}\n  true: {python: x:Y}\n") == [
        ":5: components.1: name '1' is not an identifier (ASCII letters, digits, _; "
        "not starting with a digit)"]


def test_yaml_syntax_error_names_the_line(tmp_path: Path) -> None:
    got = problems(tmp_path, GOOD_HEAD + "  a: {python: x:Y\n  b: 1\n")
    assert len(got) == 1 and got[0].startswith(":6: YAML syntax error: expected ',' or '}'")


def test_document_must_be_a_mapping(tmp_path: Path) -> None:
    assert problems(tmp_path, "- a\n- b\n") == [
        ":1: a scenario must be a mapping of fields (name, duration, tick, components, ...)"]


def test_empty_file_lists_the_required_fields(tmp_path: Path) -> None:
    assert problems(tmp_path, "") == [
        ": name: field 'name' is required", ": duration: field 'duration' is required",
        ": tick: field 'tick' is required", ": components: field 'components' is required"]


def test_duplicate_key(tmp_path: Path) -> None:
    got = problems(tmp_path, GOOD_HEAD + "  a: {python: x:Y}\n  a: {python: x:Z}\n")
    assert got == [":6: components.a: duplicate key 'a' (first at line 5)"]


def test_unknown_fields_with_suggestions(tmp_path: Path) -> None:
    got = problems(tmp_path, GOOD_HEAD + "  a:\n    python: x:Y\n    perod: 0.1\n"
                   "colour: red\nrecord: {inclde: ['*']}\n")
    assert got == [":7: components.a.perod: unknown field 'perod' (did you mean 'period'?)",
                   ":8: colour: unknown field 'colour'",
                   ":9: record.inclde: unknown field 'inclde' (did you mean 'include'?)"]


def test_wrong_types_and_ranges_show_the_value(tmp_path: Path) -> None:
    text = ("name: s\nduration: -2\ntick: fast\nstart_time: .nan\ncomponents:\n"
            "  v:\n    fmu: Bicycle\n    parameters: {m: heavy, Iz: .inf}\n"
            "    uncertainty: {m: {scale: x}}\n")
    assert problems(tmp_path, text) == [
        ":2: duration: Input should be greater than 0 (got -2)",
        ":3: tick: Input should be a valid number (got 'fast')",
        ":4: start_time: Input should be a finite number (got nan)",
        ":8: components.v.parameters.m: Input should be a valid number (got 'heavy')",
        ":8: components.v.parameters.Iz: Input should be a finite number (got inf)",
        ":9: components.v.uncertainty.m.scale: Input should be a valid number (got 'x')",
    ]


def test_periods_and_duration_must_be_whole_ticks(tmp_path: Path) -> None:
    text = ("name: s\nduration: 1.005\ntick: 0.01\ncomponents:\n"
            "  a: {python: x:Y, period: 0.015}\n  b: {python: x:Y, period: 0.005}\n"
            "  c: {python: x:Y, period: 0.3}\n")
    assert problems(tmp_path, text) == [
        ":2: duration: duration 1.005 s is not a whole number of ticks of 0.01 s",
        ":5: components.a.period: period 0.015 s is not a whole multiple of tick 0.01 s",
        ":6: components.b.period: period 0.005 s is not a whole multiple of tick 0.01 s",
    ]


def test_component_kind_and_class_path(tmp_path: Path) -> None:
    text = GOOD_HEAD + ("  both: {python: x:Y, fmu: Bicycle}\n  none: {period: 0.01}\n"
                        "  p: {python: controllers.backstepping.component}\n")
    kind = ("a component needs exactly one of 'fmu:' (built-in name or path to a .fmu) or "
            "'python:' (module:Class)")
    assert problems(tmp_path, text) == [
        f":5: components.both: {kind}", f":6: components.none: {kind}",
        ":7: components.p.python: python must read 'package.module:Class' "
        "(got 'controllers.backstepping.component')"]


def test_names_are_identifiers_and_unique(tmp_path: Path) -> None:
    text = GOOD_HEAD + ("  2fast: {python: x:Y}\n  my-ctrl: {python: x:Y}\n  wind: {python: x:Y}\n"
                        "sources:\n  wind: {kind: constant, value: 1}\n")
    assert problems(tmp_path, text) == [
        ":5: components.2fast: name '2fast' is not an identifier (ASCII letters, digits, _; "
        "not starting with a digit)",
        ":6: components.my-ctrl: name 'my-ctrl' is not an identifier (ASCII letters, digits, "
        "_; not starting with a digit)",
        ":9: sources.wind: name 'wind' is already used in components"]


def test_fmu_names_and_files(tmp_path: Path) -> None:
    (tmp_path / "real.fmu").write_bytes(b"PK")
    text = GOOD_HEAD + ("  a: {fmu: Vehicle9DOF}\n  b: {fmu: plants/missing.fmu}\n"
                        "  c: {fmu: real.fmu}\n  d: {fmu: ''}\n")
    assert problems(tmp_path, text) == [
        ":5: components.a.fmu: 'Vehicle9DOF' is neither a built-in FMU (Bicycle, Vehicle8DOF, "
        "Bicycle-fmi3, Vehicle8DOF-fmi3) nor a path ending in .fmu",
        f":6: components.b.fmu: FMU file 'plants/missing.fmu' not found (looked at "
        f"{tmp_path / 'plants/missing.fmu'})",
        ":8: components.d.fmu: String should have at least 1 character (got '')"]


def test_source_problems(tmp_path: Path) -> None:
    text = GOOD_HEAD + ("  a: {python: x:Y}\nsources:\n  w: {kind: wave}\n  n: {value: 1}\n"
                        "  g: {kind: gust, amplitude: 1, start: 0, duration: -1}\n"
                        "  r: {kind: ramp, start: 0, end: 1, t_start: 2, t_end: 1}\n"
                        "  t: {kind: table, points: [[0, 1], [0, 2]]}\n"
                        "  e: {kind: table, points: []}\n"
                        "  s: {kind: step, initial: 0, final: 1}\n")
    kinds = "kind must be one of constant, step, ramp, gust, table"
    assert problems(tmp_path, text) == [
        f":7: sources.w: {kinds} (got 'wave')",
        f":8: sources.n: {kinds} (got None)",
        ":9: sources.g.duration: Input should be greater than 0 (got -1)",
        ":10: sources.r: t_end (1.0) must be after t_start (2.0)",
        ":11: sources.t: point 1 abscissa 0.0 is not greater than point 0 abscissa 0.0: "
        "abscissas must strictly increase",
        ":12: sources.e.points: List should have at least 1 item after validation, not 0",
        ":13: sources.s.at: field 'at' is required",
    ]


def test_connection_problems(tmp_path: Path) -> None:
    text = GOOD_HEAD + ("  a: {python: x:Y}\nconnections:\n  - a => b\n  - a.x -> b\n"
                        "  - {from: a.x, to: b.y, delay: -1}\n  - {from: 'a b', to: c}\n"
                        "  - {from: a.x, to: b.y, lag: 1}\n  - 3\n")
    assert problems(tmp_path, text) == [
        ":7: connections[0]: connection 'a => b' must read 'source -> destination'",
        ":8: connections[1]: connection a.x -> b: either both sides name a port (a.x -> b.y) "
        "or neither (a -> b)",
        ":9: connections[2].delay: Input should be greater than or equal to 0 (got -1)",
        ":10: connections[3].from: from must read 'component' or 'component.port' (got 'a b')",
        ":11: connections[4].lag: unknown field 'lag'",
        ":12: connections[5]: Input should be a valid dictionary or instance of Connection (got 3)",
    ]


def test_override_problems_are_named(tmp_path: Path) -> None:
    text = GOOD_HEAD + "  a: {python: x:Y}\nconnections:\n  - a -> b\n"
    usage = "an override reads PATH=VALUE, e.g. components.controller.parameters.ke=2.0"
    assert problems(tmp_path, text, ("tick", "=3", "connections.4.delay=1",
                                     "connections.0.delay=1", "name.x=1", "tick=[1",
                                     "duration=-1", "components.a.period.x=2")) == [
        f": --set: 'tick': {usage}",
        f": --set: '=3': {usage}",
        ": --set: 'connections.4.delay=1': connections is a list of 1 items; '4' is no index",
        ": --set: 'connections.0.delay=1': connections[0] is a value, not a mapping or list",
        ": --set: 'name.x=1': name is a value, not a mapping or list",
        ": --set: 'tick=[1': value '[1' is not valid YAML: expected ',' or ']', but got "
        "'<stream end>' at column 3",
        ": duration: Input should be greater than 0 (got -1) (set by --set duration=-1)",
        ": components.a.period: Input should be a valid number (set by --set "
        "components.a.period.x=2)",
    ]


def test_all_problems_come_at_once_in_line_order(tmp_path: Path) -> None:
    text = ("name: ''\nduration: 0\ntick: 0.01\ncolour: red\ncomponents:\n"
            "  a: {python: nope}\n  b: {python: x:Y, period: 0.015}\n")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, ["description=5"])
    assert [(p.path, p.line) for p in info.value.problems] == [
        ("name", 1), ("duration", 2), ("colour", 4), ("components.a.python", 6),
        ("components.b.period", 7), ("description", None)]
    assert info.value.problems[-1] == Problem(
        "description", None, "Input should be a valid string (got 5) (set by --set description=5)")
    assert str(info.value).splitlines()[-1] == (
        f"{path}: description: Input should be a valid string (got 5) "
        "(set by --set description=5)")


def test_convert_takes_float_only(tmp_path: Path) -> None:
    text = GOOD_HEAD + ("  a: {python: x:Y}\nconnections:\n  - {from: a.x, to: b.y, convert: int}\n"
                        "  - {from: a.x, to: b.z, convert: float}\n")
    assert problems(tmp_path, text) == [
        ":7: connections[0].convert: Input should be 'float' (got 'int')"]
