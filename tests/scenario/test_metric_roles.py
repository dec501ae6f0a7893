"""The scenario's roles (`metrics: {vehicle, controller, planner}`): checked at load,
resolved with the role's own name as the default, left out of dumps when unset."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.errors import ScenarioError
from cosim.scenario.loader import load_scenario, scenario_from_dict
from cosim.scenario.roles import resolve_roles

SCENARIO = """\
name: renamed
duration: 1.0
tick: 0.01
components:
  car: {fmu: Bicycle}
  ctl: {python: controllers.backstepping:BacksteppingController}
metrics:
  skip_s: 0.5
  vehicle: kar
  controller: ctl
"""


def _file(tmp_path: Path, text: str = SCENARIO) -> Path:
    path = tmp_path / "renamed.yaml"
    path.write_text(text)
    return path


def test_a_role_naming_no_component_is_one_line_with_file_line_field_value_and_components(tmp_path):
    path = _file(tmp_path)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    assert str(caught.value) == (f"{path}:9: metrics.vehicle: 'kar' is not a component of this "
                                 "scenario (its components: car, ctl) (did you mean 'car'?)")


def test_cosim_validate_of_a_bad_role_exits_2_with_that_line(tmp_path, capsys):
    path = _file(tmp_path)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {path}:9: metrics.vehicle: 'kar' is not a component of this scenario "
                   "(its components: car, ctl) (did you mean 'car'?)"]


def test_a_role_set_on_the_command_line_is_checked_and_says_so(tmp_path):
    path = _file(tmp_path, SCENARIO.replace("  vehicle: kar\n", ""))
    assert load_scenario(path).metrics.vehicle is None
    with pytest.raises(ScenarioError, match=r"metrics\.planner: 'plan' is not a component .*"
                                            r"\(set by --set metrics\.planner=plan\)"):
        load_scenario(path, overrides=["metrics.planner=plan"])
    assert load_scenario(path, overrides=["metrics.vehicle=car"]).metrics.vehicle == "car"


def test_roles_are_strict_strings():
    base = {"name": "x", "duration": 1.0, "tick": 0.1, "components": {"car": {"fmu": "Bicycle"}}}
    for bad in (3, "", ["car"]):
        with pytest.raises(ScenarioError, match=r"metrics\.vehicle"):
            scenario_from_dict({**base, "metrics": {"vehicle": bad}})


def test_dumps_leave_unset_roles_out_and_keep_set_ones(tmp_path):
    path = _file(tmp_path, SCENARIO.replace("  vehicle: kar\n", ""))
    dumped = load_scenario(path).model_dump(mode="json", by_alias=True)
    assert dumped["metrics"]["controller"] == "ctl"
    assert "vehicle" not in dumped["metrics"] and "planner" not in dumped["metrics"]
    assert scenario_from_dict(dumped).model_dump(mode="json", by_alias=True) == dumped


@pytest.mark.parametrize("scenario, present, expected", [
    ({"components": {"vehicle": {}, "controller": {}, "planner": {}}}, (),
     {"vehicle": "vehicle", "controller": "controller", "planner": "planner"}),
    ({"components": {"car": {}, "controller": {}}, "metrics": {"vehicle": "car"}}, (),
     {"vehicle": "car", "controller": "controller", "planner": None}),
    ({"components": {"ball": {}}}, (), {"vehicle": None, "controller": None, "planner": None}),
    ({"name": "old manifest"}, ("vehicle", "road_friction"),
     {"vehicle": "vehicle", "controller": None, "planner": None}),
])
def test_resolve_roles_defaults_to_the_roles_own_names_when_present(scenario, present, expected):
    assert resolve_roles(scenario, present) == expected
