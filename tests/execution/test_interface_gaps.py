"""Interface completeness before t = 0 (cosim.execution.completeness): a plant-contract
output the name map leaves out, and an input nothing drives, are warnings of
`cosim validate` and `cosim run` (once, before tick 0), errors with --strict."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.engine.startup import StartupClock
from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.execution.validate import validate_scenario
from cosim.fmu.build import ensure_fmu
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import SCENARIOS_DIR

LANE = (SCENARIOS_DIR / "lane_keeping.yaml").read_text()
DELTA = "  - controller.delta -> vehicle.delta\n"
# where the plant's and the controller's problems point
VEHICLE_LINE = LANE.splitlines().index("  vehicle:") + 1
CONTROLLER_LINE = next(i for i, line in enumerate(LANE.splitlines(), 1)
                       if line.startswith("  controller:"))
CONTRACT = ("delta", "torque", "wind_fx", "wind_fy", "mu", "x", "y", "psi", "vx", "vy", "r",
            "ax", "ay", "phi", "omega_fl", "omega_fr", "omega_rl", "omega_rr")


def lane_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "lane.yaml"
    path.write_text(text.replace("duration: 45.0", "duration: 0.05"))
    return path


def foreign_bicycle(tmp_path: Path) -> Path:
    """The built-in Bicycle with every variable renamed veh_<name> (a foreign FMU)."""
    src = Path(ensure_fmu("Bicycle"))
    dst = tmp_path / "foreign.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "modelDescription.xml":
                data = re.sub(rb'<ScalarVariable name="', b'<ScalarVariable name="veh_', data)
            zout.writestr(info.filename, data)
    return dst


def foreign_lane(tmp_path: Path, leave_out: str) -> Path:
    names = ", ".join(f"{n}: veh_{n}" for n in CONTRACT if n != leave_out)
    return lane_file(tmp_path, LANE.replace(
        "    fmu: Vehicle8DOF\n    parameters: {vx0: 10.0, cx: 0.42}\n",
        f"    fmu: {foreign_bicycle(tmp_path)}\n    variables: {{{names}}}\n"))


def test_a_plant_output_the_name_map_leaves_out_is_reported_twice(tmp_path) -> None:
    yaml = foreign_lane(tmp_path, "r")
    gaps = validate_scenario(load_scenario(yaml))["warnings"]
    assert gaps == [
        f"{yaml}:{VEHICLE_LINE}: components.vehicle: plant 'vehicle' does not provide the "
        "plant-contract output r (docs/plant-contract.md)",
        f"{yaml}:{CONTROLLER_LINE}: components.controller: input not connected, held at its "
        "start value: r = 0 (no plant provides it)"]
    with pytest.raises(UserError) as info:
        validate_scenario(load_scenario(yaml), strict=True)
    assert str(info.value).splitlines() == [f"{g} (--strict)" for g in gaps]


def test_an_unconnected_plant_input_is_a_warning_and_strict_an_error(tmp_path, capsys) -> None:
    yaml = lane_file(tmp_path, LANE.replace(DELTA, ""))
    assert main(["validate", str(yaml)]) == 0
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        f"warning: {yaml}:{VEHICLE_LINE}: components.vehicle: input not connected, held at its "
        "start value: delta = 0"]
    assert "ok (3 components" in captured.out
    assert main(["validate", str(yaml), "--strict"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"error: {yaml}:{VEHICLE_LINE}: components.vehicle: input not connected, held at its start "
        "value: delta = 0 (--strict)"]


def test_a_complete_scenario_has_no_gap(tmp_path) -> None:
    assert validate_scenario(load_scenario(lane_file(tmp_path, LANE)), strict=True)["warnings"] == []


def test_neutral_disturbance_inputs_of_a_mapped_plant_are_no_gap(tmp_path) -> None:
    yaml = lane_file(tmp_path, LANE.replace("{vx0: 10.0, cx: 0.42}", "{vx0: 10.0, cx: 0.42}\n"
                                            "    variables: {}\n"))
    assert validate_scenario(load_scenario(yaml))["warnings"] == []  # wind 0 and mu 1: neutral


def test_run_prints_the_warning_once_before_tick0(tmp_path, capsys) -> None:
    yaml = lane_file(tmp_path, LANE.replace(DELTA, ""))
    assert main(["run", str(yaml), "--transport", "inproc", "--no-figures",
                 "--out", str(tmp_path / "run")]) == 0
    warnings = [l for l in capsys.readouterr().err.splitlines() if l.startswith("warning:")]
    assert warnings == [f"warning: {yaml}:{VEHICLE_LINE}: components.vehicle: input not "
                        "connected, held at its start value: delta = 0"]
    clock, seen = StartupClock.from_now(), []
    run_scenario(load_scenario(yaml), tmp_path / "run2", progress=False, clock=clock,
                 on_warning=lambda text: seen.append("tick0" in clock.marks))
    assert seen == [False]


def test_run_strict_exits_2_before_tick0(tmp_path, capsys) -> None:
    yaml = foreign_lane(tmp_path, "r")
    assert main(["run", str(yaml), "--transport", "inproc", "--no-figures", "--strict",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "plant 'vehicle' does not provide the plant-contract output r" in err
    assert not (tmp_path / "run" / "signals.csv").exists()
