"""Tests of cosim.engine.wiring: short-form expansion, precedence, and every bad-connection message."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.component import Port
from cosim.errors import WiringError
from cosim.scenario.loader import Scenario, load_scenario
from cosim.engine.wiring import Edge, resolve_wiring, unconnected_inputs

PORTS = {
    "vehicle": ((Port("delta", unit="rad"), Port("torque", unit="N.m"), Port("wind_fy", unit="N"),
                 Port("mu", unit="1")),
                (Port("x", unit="m"), Port("y", unit="m"), Port("psi", unit="rad"),
                 Port("vx", unit="m/s"))),
    "controller": ((Port("x", unit="m"), Port("y", unit="m"), Port("psi", unit="rad"),
                    Port("vx", unit="m/s"), Port("ref_x", size=4, unit="m")),
                   (Port("delta", unit="rad"), Port("torque", unit="N.m"))),
    "planner": ((Port("x", unit="m"), Port("y", unit="m")),
                (Port("ref_x", size=4, unit="m"), Port("v_ref", unit="m/s"))),
    "wind": ((), (Port("value", unit=""),)),
}

HEADER = "name: w\nduration: 1\ntick: 0.01\ncomponents:\n  vehicle: {fmu: Bicycle}\n" \
         "  controller: {python: 'a:B'}\n  planner: {python: 'a:C'}\n" \
         "sources:\n  wind: {kind: constant, value: 0}\nconnections:\n"


def scenario_with(tmp_path: Path, *connections: str) -> Scenario:
    """A scenario whose connections are the given YAML list items (line 11 onwards)."""
    path = tmp_path / "wiring.yaml"
    path.write_text(HEADER + "".join(f"  - {c}\n" for c in connections))
    return load_scenario(path)


def wiring_problems(tmp_path: Path, *connections: str) -> list[str]:
    scenario = scenario_with(tmp_path, *connections)
    with pytest.raises(WiringError) as info:
        resolve_wiring(scenario, PORTS)
    prefix = f"{tmp_path / 'wiring.yaml'}:"
    lines = str(info.value).splitlines()
    assert all(line.startswith(prefix) for line in lines)
    assert [p.line for p in info.value.problems] == sorted(p.line for p in info.value.problems)
    return [line[len(prefix):] for line in lines]


def test_short_forms_expand_by_matching_names_with_delay(tmp_path: Path) -> None:
    scenario = scenario_with(tmp_path, "vehicle -> controller", "planner -> controller",
                             "{from: controller, to: vehicle, delay: 1}",
                             "wind.value -> vehicle.wind_fy", "vehicle -> planner")
    assert resolve_wiring(scenario, PORTS) == [
        Edge("vehicle", "x", "controller", "x", 0), Edge("vehicle", "y", "controller", "y", 0),
        Edge("vehicle", "psi", "controller", "psi", 0), Edge("vehicle", "vx", "controller", "vx", 0),
        Edge("planner", "ref_x", "controller", "ref_x", 0),
        Edge("controller", "delta", "vehicle", "delta", 1),
        Edge("controller", "torque", "vehicle", "torque", 1),
        Edge("wind", "value", "vehicle", "wind_fy", 0),  # unit "" matches "N"
        Edge("vehicle", "x", "planner", "x", 0), Edge("vehicle", "y", "planner", "y", 0),
    ]


def test_explicit_connection_takes_precedence_over_short_form(tmp_path: Path) -> None:
    scenario = scenario_with(tmp_path, "vehicle -> controller", "planner.ref_x -> controller.x")
    with pytest.raises(WiringError, match="size mismatch"):  # explicit edges are still checked
        resolve_wiring(scenario, PORTS)
    ports = dict(PORTS, planner=((), (Port("x_alt", unit="m"),)))
    scenario = scenario_with(tmp_path, "vehicle -> controller", "planner.x_alt -> controller.x")
    edges = resolve_wiring(scenario, ports)
    assert Edge("planner", "x_alt", "controller", "x", 0) in edges
    assert Edge("vehicle", "x", "controller", "x", 0) not in edges
    assert Edge("vehicle", "y", "controller", "y", 0) in edges


def test_short_form_mismatch_overridden_by_explicit_edge_is_not_reported(tmp_path: Path) -> None:
    ports = dict(PORTS, planner=((), (Port("psi", unit="deg"),)))
    scenario = scenario_with(tmp_path, "planner -> controller", "vehicle.psi -> controller.psi")
    assert resolve_wiring(scenario, ports) == [Edge("vehicle", "psi", "controller", "psi", 0)]
    scenario = scenario_with(tmp_path, "planner -> controller")
    with pytest.raises(WiringError, match=r"unit mismatch on planner.psi -> controller.psi: "
                                          r"output in 'deg', input in 'rad'"):
        resolve_wiring(scenario, ports)


def test_unknown_component_and_port(tmp_path: Path) -> None:
    assert wiring_problems(tmp_path, "vehicel -> controller", "vehicle.xx -> controller.x",
                           "controller.delta -> vehicle.steer") == [
        "11: connections[0]: vehicel -> controller: no component or source named 'vehicel' "
        "(did you mean 'vehicle'?); known: vehicle, controller, planner, wind",
        "12: connections[1]: vehicle.xx -> controller.x: 'vehicle' has no output 'xx' "
        "(did you mean 'x'?); its outputs: x, y, psi, vx",
        "13: connections[2]: controller.delta -> vehicle.steer: 'vehicle' has no input 'steer'; "
        "its inputs: delta, torque, wind_fy, mu",
    ]


def test_wrong_causality_on_either_side(tmp_path: Path) -> None:
    assert wiring_problems(tmp_path, "vehicle.delta -> controller.x",
                           "vehicle.x -> controller.delta") == [
        "11: connections[0]: vehicle.delta -> controller.x: wrong causality: vehicle.delta is "
        "an input, but a connection's source must be an output",
        "12: connections[1]: vehicle.x -> controller.delta: wrong causality: controller.delta "
        "is an output, but a connection's destination must be an input",
    ]


def test_size_and_unit_mismatch(tmp_path: Path) -> None:
    assert wiring_problems(tmp_path, "planner.ref_x -> vehicle.delta",
                           "vehicle.vx -> controller.x") == [
        "11: connections[0]: planner.ref_x -> vehicle.delta: size mismatch: output has 4 "
        "values, input takes 1",
        "12: connections[1]: vehicle.vx -> controller.x: unit mismatch: output in 'm/s', "
        "input in 'm'",
    ]


def test_input_driven_twice(tmp_path: Path) -> None:
    assert wiring_problems(tmp_path, "vehicle.x -> controller.x", "planner.ref_x -> controller.ref_x",
                           "vehicle.y -> controller.x") == [
        "13: connections[2]: input controller.x is driven twice: by vehicle.y here and by "
        "vehicle.x (connections[0], line 11)",
    ]
    assert wiring_problems(tmp_path, "vehicle -> planner", "controller -> planner",
                           "{from: vehicle, to: planner, delay: 1}") == [
        "12: connections[1]: controller -> planner: no output of 'controller' has the name of "
        "an input of 'planner' (outputs of controller: delta, torque; inputs of planner: x, y)",
        "13: connections[2]: input planner.x is driven twice: by vehicle.x here and by "
        "vehicle.x (connections[0], line 11)",
        "13: connections[2]: input planner.y is driven twice: by vehicle.y here and by "
        "vehicle.y (connections[0], line 11)",
    ]


def test_unsupported_fmu_variable_is_explained(tmp_path: Path) -> None:
    scenario = scenario_with(tmp_path, "controller.delta -> vehicle.gear")
    with pytest.raises(WiringError) as info:
        resolve_wiring(scenario, PORTS, {"vehicle": {"gear": "Integer (only Float64/Real signals "
                                                              "are supported)"}})
    assert str(info.value).endswith("vehicle.gear cannot be connected: it is Integer "
                                    "(only Float64/Real signals are supported)")


def test_scenario_built_in_memory_has_no_file_or_line() -> None:
    scenario = Scenario.model_validate({
        "name": "m", "duration": 1, "tick": 0.1,
        "components": {"vehicle": {"fmu": "Bicycle"}, "controller": {"python": "a:B"}},
        "connections": ["vehicle.nope -> controller.x"]})
    with pytest.raises(WiringError) as info:
        resolve_wiring(scenario, PORTS)
    assert str(info.value).startswith("<scenario>: connections[0]: vehicle.nope -> controller.x:")
    assert info.value.problems[0].line is None


def test_unconnected_inputs_in_declaration_order(tmp_path: Path) -> None:
    scenario = scenario_with(tmp_path, "vehicle -> controller", "controller -> vehicle")
    edges = resolve_wiring(scenario, PORTS)
    assert [(c, p.name) for c, p in unconnected_inputs(edges, PORTS)] == [
        ("vehicle", "wind_fy"), ("vehicle", "mu"), ("controller", "ref_x"),
        ("planner", "x"), ("planner", "y")]
