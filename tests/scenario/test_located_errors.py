"""Errors that used to lose their place: an algebraic loop (file, line, --set), a
`!!python` tag in --set (one line), a duration blamed for the tick's --set, a directory
or FIFO given as a scenario or FMU, the `connections[1].delay` path form in --set,
non-ASCII names and a shipped class without parameters."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
from pydantic import BaseModel, ConfigDict

from cosim.cli.app import main
from cosim.component import Port
from cosim.engine.schedule import step_order
from cosim.engine.wiring import resolve_wiring
from cosim.errors import ScenarioError, UserError, WiringError
from cosim.scenario import known_classes
from cosim.scenario.loader import load_scenario
from cosim.scenario.shipped import resolve_scenario
from tests.helpers.paths import REPO_ROOT

OPEN_LOOP = REPO_ROOT / "scenarios" / "open_loop.yaml"

LOOP = ("name: loop\nduration: 1.0\ntick: 0.1\ncomponents:\n"
        "  a: {python: 'x:Echo'}\n  b: {python: 'x:Echo'}\n"
        "connections:\n  - a.y -> b.u\n  - {from: b.y, to: a.u, delay: 1}\n")   # lines 8, 9
ECHO_PORTS = {"a": ((Port("u"),), (Port("y"),)), "b": ((Port("u"),), (Port("y"),))}
LOOP_MESSAGE = ("algebraic loop between components with direct feedthrough: a -> b -> a; "
                "mark one of these connections with delay: 1")


def _loop_error(path: Path, overrides: tuple[str, ...] = ()) -> tuple[UserError, WiringError]:
    """The located error and the engine's own for the step order of a scenario file."""
    scenario = load_scenario(path, overrides)
    edges = resolve_wiring(scenario, ECHO_PORTS)
    with pytest.raises(WiringError) as info:
        step_order(["a", "b"], {"a": True, "b": True}, edges)
    located = scenario.locate(info.value)
    assert located is not None
    return located, info.value


def _problems(tmp_path: Path, text: str, overrides: tuple[str, ...] = ()) -> list[str]:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    return [line.removeprefix(str(path)) for line in str(info.value).splitlines()]


# ---- 1. algebraic loop ---------------------------------------------------------------

def test_algebraic_loop_names_the_file_and_the_loops_connections(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text(LOOP.replace(", delay: 1", ""))
    located, raw = _loop_error(path)
    assert str(raw) == f"<scenario>: connections: {LOOP_MESSAGE}"  # what the engine knows
    assert str(located) == (f"{path}:8: connections[0]: {LOOP_MESSAGE} "
                            "(the loop: connections[0] at line 8, connections[1] at line 9)")
    assert isinstance(located, WiringError)


@pytest.mark.parametrize("override", ["connections.1.delay=0", "connections[1].delay=0"])
def test_algebraic_loop_made_by_a_set_names_the_set(tmp_path, override):
    path = tmp_path / "loop.yaml"
    path.write_text(LOOP)
    located, _ = _loop_error(path, (override,))
    assert str(located) == (f"{path}:9: connections[1]: {LOOP_MESSAGE} "
                            "(the loop: connections[0] at line 8, connections[1] at line 9) "
                            f"(set by --set {override})")


def test_self_loop_is_located_at_its_connection(tmp_path):
    path = tmp_path / "self.yaml"
    path.write_text(LOOP.replace("  - a.y -> b.u\n", "  - a.y -> a.u\n")
                    .replace("to: a.u, delay: 1", "to: b.u"))
    scenario = load_scenario(path)
    with pytest.raises(WiringError) as info:
        step_order(["a", "b"], {"a": True, "b": True}, resolve_wiring(scenario, ECHO_PORTS))
    assert str(scenario.locate(info.value)) == (
        f"{path}:8: connections[0]: algebraic loop: a -> a (y -> u) needs delay: 1")


def test_locate_leaves_other_errors_alone(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text(LOOP)
    scenario = load_scenario(path)
    resolved = WiringError(path, [scenario.problem(("connections", 0), "a.y -> b.u: nope")])
    assert scenario.locate(resolved) is None  # already located
    assert scenario.locate(UserError("algebraic loop")) is None
    assert scenario.locate(KeyboardInterrupt()) is None


# ---- 2. a tag in --set or in the file: one line ----------------------------------------

def test_python_tag_in_set_is_one_line(tmp_path):
    text = "name: s\nduration: 1\ntick: 0.01\ncomponents:\n  a: {python: x:Y}\n"
    got = _problems(tmp_path, text, ("duration=!!python/object:os.system ls",))
    assert got == [": --set: 'duration=!!python/object:os.system ls': value "
                   "'!!python/object:os.system ls' cannot be read: the tag "
                   "'!!python/object:os.system' is not supported (a scenario holds plain "
                   "values: numbers, strings, true/false, lists, mappings)"]


def test_unknown_tag_in_the_file_is_one_line(tmp_path):
    text = "name: s\nduration: !!python/object:os.system ls\ntick: !foo 0.01\ncomponents: {}\n"
    got = _problems(tmp_path, text)
    assert got[:2] == [
        ":2: duration: the tag '!!python/object:os.system' is not supported (a scenario "
        "holds plain values: numbers, strings, true/false, lists, mappings)",
        ":3: tick: the tag '!foo' is not supported (a scenario holds plain values: "
        "numbers, strings, true/false, lists, mappings)"]


# ---- 3. the tick's --set in problems located at the duration or a period ----------------

def test_tick_set_on_the_command_line_is_named(tmp_path):
    text = ("name: s\nduration: 10.0\ntick: 0.01\ncomponents:\n"
            "  a: {python: x:Y, period: 0.01}\n")
    assert _problems(tmp_path, text, ("tick=20",)) == [
        ":2: duration: duration 10 s is not a whole number of ticks of 20 s "
        "(tick set by --set tick=20)",
        ":5: components.a.period: period 0.01 s is not a whole multiple of tick 20 s "
        "(tick set by --set tick=20)"]
    assert _problems(tmp_path, text.replace("tick: 0.01", "tick: 20")) == [
        ":2: duration: duration 10 s is not a whole number of ticks of 20 s",
        ":5: components.a.period: period 0.01 s is not a whole multiple of tick 20 s"]


def test_where_notes_the_fields_a_value_derives_from(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("name: s\nduration: 10.0\ntick: 0.01\ncomponents:\n  a: {python: x:Y}\n")
    scenario = load_scenario(path, ["tick=1e-300"])
    assert scenario.where(("duration",), ("tick",)) == (
        f"{path}:2: duration (tick set by --set tick=1e-300)")
    assert scenario.where(("duration",)) == f"{path}:2: duration"
    assert load_scenario(path).where(("duration",), ("tick",)) == f"{path}:2: duration"


# ---- 4. a path that is no regular file ------------------------------------------------

def test_scenario_argument_that_is_no_regular_file(tmp_path, capsys):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    cases = {tmp_path: "is a directory", fifo: "is a FIFO (named pipe)",
             Path("/dev/null"): "is a character device"}
    for path, kind in cases.items():
        with pytest.raises(ScenarioError) as info:
            resolve_scenario(path)
        assert str(info.value) == f"{path}: {kind}, not a regular file"
    assert main(["validate", str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"error: {tmp_path}: is a directory, not a regular file\n"


def test_fmu_path_that_is_a_directory(tmp_path):
    (tmp_path / "somedir.fmu").mkdir()
    text = "name: s\nduration: 1\ntick: 0.01\ncomponents:\n  v: {fmu: Bicycle}\n"
    assert _problems(tmp_path, text, ("components.v.fmu=somedir.fmu",)) == [
        f": components.v.fmu: FMU 'somedir.fmu' is a directory, not an .fmu file (looked at "
        f"{tmp_path / 'somedir.fmu'}) (set by --set components.v.fmu=somedir.fmu)"]


# ---- 5. --set takes the path an error prints -------------------------------------------

def test_set_takes_the_bracket_index_form(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text(LOOP)
    dotted = load_scenario(path, ["connections.1.delay=0"])
    bracketed = load_scenario(path, ["connections[1].delay=0"])
    assert load_scenario(path).connections[1].delay == 1
    assert dotted.connections[1].delay == bracketed.connections[1].delay == 0
    assert bracketed.where(("connections", 1, "delay")) == (
        f"{path}: connections[1].delay (set by --set connections[1].delay=0)")
    assert _problems(tmp_path, LOOP, ("connections[1].delay=2", "components[0].period=1",
                                      "connections[7].delay=1", "[0].x=1")) == [
        ": --set: 'components[0].period=1': components is a mapping, not a list, so [0] is "
        "no index",
        ": --set: 'connections[7].delay=1': connections is a list of 2 items; '7' is no index",
        ": --set: '[0].x=1': an override reads PATH=VALUE, e.g. "
        "components.controller.parameters.ke=2.0",
        ": connections[1].delay: Input should be less than or equal to 1 (got 2) "
        "(set by --set connections[1].delay=2)"]


# ---- 6. names and parameters -----------------------------------------------------------

def test_non_ascii_name_is_refused_as_not_ascii(tmp_path):
    text = "name: s\nduration: 1\ntick: 0.01\ncomponents:\n  véhicule: {python: x:Y}\n"
    assert _problems(tmp_path, text) == [
        ":5: components.véhicule: name 'véhicule' is not an identifier (ASCII letters, "
        "digits, _; not starting with a digit)"]


def test_shipped_class_without_parameters_says_it_takes_none(monkeypatch):
    class NoParameters(BaseModel):
        model_config = ConfigDict(extra="forbid")

    monkeypatch.setattr(known_classes, "parameters_model", lambda class_path: NoParameters)
    assert known_classes.parameter_problems(
        ("components", "a"), {"python": "m:Bare", "parameters": {"mode": 1}}) == [
        (("components", "a", "parameters", "mode"),
         "unknown parameter 'mode': m:Bare takes no parameters")]


@pytest.mark.parametrize("start", [1e17, -1e12])
def test_a_start_time_whose_ticks_float64_cannot_tell_apart_is_refused(start):
    with pytest.raises(ScenarioError) as raised:
        load_scenario(OPEN_LOOP, [f"start_time={start!r}"])
    latest = abs(start) + 10.0
    assert str(raised.value) == (
        f"{OPEN_LOOP}: start_time: start_time {start:g} s is too far from 0 for ticks of "
        f"0.01 s: times near {latest:g} s are only resolved to {math.ulp(latest):g} s (at "
        f"most 0.001 of a tick); use a start time nearer 0 (set by --set start_time={start!r})")


def test_a_unix_time_as_start_time_is_fine():
    assert load_scenario(OPEN_LOOP, ["start_time=1.7e9"]).start_time == 1.7e9
