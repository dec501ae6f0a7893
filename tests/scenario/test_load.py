"""Tests of loading valid scenarios: fields, tick arithmetic, overrides, derived views, schema."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario.loader import (Connection, FmuSpec, GustSource, PythonSpec, RecordSpec, Scenario,
                            TableSource, json_schema, load_scenario)

LANE_CHANGE = """\
name: lane_change
description: "double lane change with wind"
duration: 20.0
tick: 0.01
components:
  vehicle:
    fmu: Vehicle8DOF
    parameters: {vx0: 10.0, m: 1500.0}
    uncertainty:
      m: {scale: 1.3}
      Cf: {offset: -5000.0}
  controller:
    python: controllers.backstepping:BacksteppingController
    period: 0.01
    parameters: {ls: 5.0, ke: [1, 2]}
  planner:
    python: controllers.planning:Planner
    period: 0.1
  foreign:
    fmu: ../plants/other.fmu
    variables: {delta: steerAngle}
    host: worker1
sources:
  side_wind:
    kind: gust
    amplitude: 1e3
    start: 2
    duration: 1.5
    unit: N
  mu_road:
    kind: table
    over: distance
    points: [[0, 1.0], [50, 0.5]]
    interpolation: previous
connections:
  - vehicle -> controller
  - planner -> controller
  - controller.delta -> vehicle.delta
  - {from: side_wind.value, to: vehicle.wind_fy, delay: 1}
record:
  exclude: ["planner.*"]
"""


@pytest.fixture()
def lane_change(tmp_path: Path) -> Path:
    (tmp_path / "plants").mkdir()
    (tmp_path / "plants" / "other.fmu").write_bytes(b"PK")
    (tmp_path / "scenarios").mkdir()
    path = tmp_path / "scenarios" / "lane_change.yaml"
    path.write_text(LANE_CHANGE)
    return path


def test_fields_are_read_as_typed_models(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    assert (s.name, s.description, s.duration, s.tick, s.start_time) == (
        "lane_change", "double lane change with wind", 20.0, 0.01, None)  # None: the FMU's
    assert s.components["vehicle"] == FmuSpec(fmu="Vehicle8DOF",
                                              parameters={"vx0": 10.0, "m": 1500.0},
                                              uncertainty={"m": {"scale": 1.3},
                                                           "Cf": {"offset": -5000.0}})
    assert s.components["controller"] == PythonSpec(
        python="controllers.backstepping:BacksteppingController", period=0.01,
        parameters={"ls": 5.0, "ke": [1, 2]})
    assert s.components["foreign"].variables == {"delta": "steerAngle"}
    assert s.components["foreign"].host == "worker1"
    assert s.sources["side_wind"] == GustSource(kind="gust", amplitude=1000.0, start=2.0,
                                                duration=1.5, unit="N")
    assert isinstance(s.sources["mu_road"], TableSource)
    assert s.sources["mu_road"].points == [(0.0, 1.0), (50.0, 0.5)]
    assert s.record == RecordSpec(include=["*"], exclude=["planner.*"])
    assert s.source_file == lane_change


def test_connections_parse_both_forms(lane_change: Path) -> None:
    c = load_scenario(lane_change).connections
    assert [(x.src, x.dst, x.delay) for x in c] == [
        ("vehicle", "controller", 0), ("planner", "controller", 0),
        ("controller.delta", "vehicle.delta", 0), ("side_wind.value", "vehicle.wind_fy", 1)]
    assert c[0].is_short and c[0].src_port is None and c[0].dst_component == "controller"
    assert (c[2].src_component, c[2].src_port, c[2].dst_component, c[2].dst_port) == (
        "controller", "delta", "vehicle", "delta")
    dotted = Connection.model_validate("fmu.body.v[1] -> ctrl.v")  # FMU names may hold dots
    assert (dotted.src_component, dotted.src_port) == ("fmu", "body.v[1]")


def test_tick_arithmetic_is_exact(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    assert s.total_ticks == 2000
    assert s.period_ticks("vehicle") == 1            # no period: every tick
    assert s.period_ticks("planner") == 10
    assert s.period_ticks("side_wind") == 1
    assert s.period_ticks("controller", default_period=0.05) == 1  # the scenario's wins
    assert s.period_ticks("vehicle", default_period=0.05) == 5     # the class default
    # 0.3 / 0.1 is 2.9999999999999996 in floats: the count must still be 3
    short = load_scenario(lane_change, ["duration=0.3", "tick=0.1", "components.controller.period=0.1",
                                        "components.planner.period=0.3"])
    assert (short.total_ticks, short.period_ticks("planner")) == (3, 3)


def test_bad_default_period_is_reported_with_the_component(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    with pytest.raises(ScenarioError) as info:
        s.period_ticks("vehicle", default_period=0.015)
    assert str(info.value) == (f"{lane_change}:6: components.vehicle.period: period 0.015 s "
                               "(the component's default period) is not a whole multiple of "
                               "tick 0.01 s")
    with pytest.raises(ScenarioError, match="no component named 'nope'"):
        s.period_ticks("nope")


def test_plant_parameters_apply_uncertainty(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    assert s.plant_parameters("vehicle", {"Cf": 57500.0, "m": 1.0}) == {
        "vx0": 10.0, "m": 1500.0 * 1.3, "Cf": 52500.0}
    # the controller keeps its nominal values: nothing in its spec changes
    assert s.components["vehicle"].parameters == {"vx0": 10.0, "m": 1500.0}
    with pytest.raises(ScenarioError) as info:
        s.plant_parameters("vehicle")
    assert str(info.value) == (f"{lane_change}:11: components.vehicle.uncertainty.Cf: "
                               "uncertainty on 'Cf', which has no value in parameters nor a "
                               "start value in the FMU")


def test_python_components_include_sources(lane_change: Path) -> None:
    specs = load_scenario(lane_change).python_components()
    assert list(specs) == ["controller", "planner", "side_wind", "mu_road"]
    assert specs["side_wind"] == PythonSpec(
        python="cosim.sources:Gust",
        parameters={"amplitude": 1000.0, "start": 2.0, "duration": 1.5, "base": 0.0, "unit": "N"})
    assert specs["mu_road"].parameters == {"over": "distance", "points": [[0.0, 1.0], [50.0, 0.5]],
                                           "interpolation": "previous", "unit": ""}


def test_fmu_components_and_paths(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    fmus = s.fmu_components()
    assert list(fmus) == ["vehicle", "foreign"]
    assert s.resolve_fmu_path(fmus["vehicle"]) == "Vehicle8DOF"
    resolved = s.resolve_fmu_path(fmus["foreign"])
    assert resolved == lane_change.parent / "../plants/other.fmu"
    assert resolved.resolve() == (lane_change.parent.parent / "plants" / "other.fmu").resolve()
    absolute = FmuSpec(fmu=str(resolved.resolve()))
    assert s.resolve_fmu_path(absolute) == resolved.resolve()


def test_overrides_are_yaml_values_at_dotted_paths(lane_change: Path) -> None:
    s = load_scenario(lane_change, [
        "components.controller.parameters.ke=2.0", "duration=5", "connections.3.delay=1",
        "components.planner.parameters.speed.v_max=5", "description=now 1e-3",
        "sources.side_wind.amplitude=1e-3", "record.include=[vehicle.*]"])
    assert s.components["controller"].parameters == {"ls": 5.0, "ke": 2.0}
    assert s.total_ticks == 500
    assert s.connections[3].delay == 1
    assert s.components["planner"].parameters == {"speed": {"v_max": 5}}
    assert s.description == "now 1e-3"
    assert s.sources["side_wind"].amplitude == 0.001
    assert s.record.include == ["vehicle.*"]


def test_loads_of_one_file_do_not_share_their_overrides(lane_change: Path) -> None:
    """The document parsed once per text is copied for each load: one load's overrides
    (which change the document and its line map) are not seen by the next; a changed
    file is parsed again."""
    overridden = load_scenario(lane_change, ["components.controller.parameters.ke=2.0",
                                             "components.vehicle.parameters.m=900"])
    assert overridden.components["controller"].parameters["ke"] == 2.0
    plain = load_scenario(lane_change)
    assert plain.components["controller"].parameters == {"ls": 5.0, "ke": [1, 2]}
    assert plain.components["vehicle"].parameters == {"vx0": 10.0, "m": 1500.0}
    mass = ("components", "vehicle", "parameters", "m")
    assert ":8: " in plain.where(mass) and ":8: " not in overridden.where(mass)
    lane_change.write_text(lane_change.read_text().replace("ls: 5.0", "ls: 6.0"))
    assert load_scenario(lane_change).components["controller"].parameters["ls"] == 6.0


def test_dump_round_trips(lane_change: Path) -> None:
    s = load_scenario(lane_change)
    dumped = s.model_dump(mode="json")
    assert dumped["connections"][3] == {"from": "side_wind.value", "to": "vehicle.wind_fy",
                                        "delay": 1}
    again = Scenario.model_validate(dumped)
    assert again.model_dump(mode="json") == dumped


def test_in_memory_scenario_runs_cross_checks() -> None:
    base = {"name": "m", "duration": 1, "tick": 0.1, "components": {"a": {"python": "x:Y"}}}
    assert Scenario.model_validate(base).total_ticks == 10
    with pytest.raises(ValueError, match=r"components\.a\.period: period 0\.25 s is not a whole "
                                         r"multiple of tick 0\.1 s"):
        Scenario.model_validate({**base, "components": {"a": {"python": "x:Y", "period": 0.25}}})


def test_record_globs() -> None:
    record = RecordSpec(include=["vehicle.*", "controller.delta"], exclude=["vehicle.omega_*"])
    assert [record.selects(n) for n in ("vehicle.x", "vehicle.omega_fl", "controller.delta",
                                        "controller.torque")] == [True, False, True, False]
    assert RecordSpec().selects("anything.at_all")


def test_json_schema_accepts_the_example_and_rejects_extras(lane_change: Path) -> None:
    jsonschema = pytest.importorskip("jsonschema")
    import yaml

    schema = json_schema()
    assert schema["title"] == "cosim scenario"
    document = yaml.safe_load(LANE_CHANGE)
    document["sources"]["side_wind"]["amplitude"] = 1000.0  # plain YAML reads 1e3 as a string
    jsonschema.validate(document, schema)
    document["components"]["vehicle"]["colour"] = "red"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(document, schema)


def test_metrics_section_is_typed(tmp_path):
    """The metrics section takes cones as [x, y] pairs and rejects unknown fields with their line."""
    from cosim.errors import ScenarioError
    from cosim.scenario.loader import load_scenario
    good = tmp_path / "good.yaml"
    good.write_text(
        "name: m\nduration: 1\ntick: 0.1\n"
        "components:\n  src: {python: cosim.sources:Constant,\n        parameters: {value: 0}}\n"
        "metrics:\n  skip_s: 0.5\n  cones: [[1, 2], [3.5, -1]]\n")
    scenario = load_scenario(good)
    assert scenario.metrics.cones == [(1.0, 2.0), (3.5, -1.0)]
    assert scenario.metrics.skip_s == 0.5
    bad = tmp_path / "bad.yaml"
    bad.write_text(good.read_text() + "  cone_radius: 2\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(bad)
    assert "bad.yaml:10" in str(err.value) and "metrics.cone_radius" in str(err.value)


def test_builtin_fmu_names_are_the_ones_fmu_build_can_build() -> None:
    """The scenario's list is written out (it must not depend on fmus/ being present); keep it in step."""
    from cosim.fmu import build as fmu_build
    from cosim.scenario.loader import BUILTIN_FMUS

    buildable = {fmu_build.fmu_file_name(m, v).removesuffix(".fmu")
                 for m in fmu_build.MODELS for v in (2, 3)}
    assert set(BUILTIN_FMUS) == buildable and len(BUILTIN_FMUS) == len(buildable)
