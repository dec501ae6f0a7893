"""scenarios/vehicle_following.yaml in closed loop: two Vehicle8DOF instances, no collision,
the time-gap policy's steady state and bounds, the follower in its lane, and the same bits over Zenoh.

The expected numbers come from the scenario file itself (the policy's fields,
the lead's table), not from recorded outputs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cosim.cli.app import main
from cosim.analysis.rundata import load_run
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "vehicle_following.yaml"
pytestmark = pytest.mark.integration


def _run(out: Path, transport: str) -> Path:
    assert main(["run", str(SCENARIO), "--out", str(out), "--transport", transport]) == 0
    return out


@pytest.fixture(scope="module")
def inproc_run(tmp_path_factory) -> Path:
    """The whole scenario, in-process, once for the module (metrics and figure included)."""
    return _run(tmp_path_factory.mktemp("following") / "inproc", "inproc")


@pytest.fixture(scope="module")
def spec():
    """(the follower's policy fields, the lead's speed table) from the scenario file."""
    scenario = load_scenario(SCENARIO)
    manoeuvre = scenario.components["planner"].parameters["manoeuvre"]
    return manoeuvre, np.array(scenario.sources["lead_profile"].points)


def _sig(run, name: str) -> np.ndarray:
    values = run.signal(name)
    assert values is not None, f"{name} not recorded"
    return values


def test_two_instances_of_one_fmu_and_no_collision(inproc_run):
    manifest = json.loads((inproc_run / "manifest.json").read_text())
    fmus = manifest["scenario"]["components"]
    assert fmus["vehicle"]["fmu"] == fmus["lead"]["fmu"] == "Vehicle8DOF"
    metrics = json.loads((inproc_run / "metrics.json").read_text())
    assert metrics["collisions"] == 0
    run = load_run(inproc_run)
    # independent of the planner: the CGs stay a body length apart plus the gap the metric saw
    chord = np.hypot(_sig(run, "lead.x") - _sig(run, "vehicle.x"), _sig(run, "lead.y") - _sig(run, "vehicle.y"))
    assert chord.min() > 4.5
    assert metrics["min_ttc"] > 1.0 and metrics["min_time_gap"] > 1.0
    assert (inproc_run / "figure_following.png").is_file()


def test_constant_lead_speed_gives_the_time_gap_steady_state(inproc_run, spec):
    manoeuvre, table = spec
    run = load_run(inproc_run)
    t, gap, vx = run.time, _sig(run, "planner.gap"), _sig(run, "vehicle.vx")
    # the table holds the lead at its top speed between its 3rd and 4th points; the last 2 s of that
    v_lead = table[2, 1]
    steady = (t >= table[3, 0] - 2.0) & (t < table[3, 0])
    assert np.all(np.abs(vx[steady] - v_lead) < 0.05)
    expected = manoeuvre["standstill"] + manoeuvre["time_gap"] * v_lead
    assert np.all(np.abs(gap[steady] - expected) < 0.15)


def test_gap_error_bounded_and_the_follower_stops_behind_the_lead(inproc_run, spec):
    manoeuvre, table = spec
    run = load_run(inproc_run)
    t = run.time
    error = _sig(run, "planner.gap") - _sig(run, "planner.gap_ref")
    initial = abs(error[0])
    assert np.all(np.abs(error) <= initial + 1e-9)            # never worse than the start ...
    caught_up = error[t >= 10.0]
    assert np.all(caught_up > -0.5)       # once caught up, never 0.5 m closer than desired ...
    assert np.all(caught_up < 2.5)        # ... and at most 2.5 m behind it, during the hard stop
    assert _sig(run, "lead.vx")[-1] < 0.01                    # the lead stopped ...
    assert _sig(run, "vehicle.vx")[-1] < 0.1                  # ... the follower nearly
    final_gap = _sig(run, "planner.gap")[-1]
    assert manoeuvre["standstill"] - 0.1 < final_gap < manoeuvre["standstill"] + 1.0
    # the lead stopped in the bend: its heading turned by more than 0.3 rad
    assert _sig(run, "lead.psi")[-1] > 0.3


def test_policy_bounds_hold_in_closed_loop_and_the_follower_keeps_its_lane(inproc_run, spec):
    manoeuvre, _ = spec
    run = load_run(inproc_run)
    a = _sig(run, "planner.a_follow")
    assert a.max() <= manoeuvre["a_max"] and a.min() >= -manoeuvre["d_max"]
    steps = a[::10]                       # the planner's period is 10 ticks
    assert np.max(np.abs(np.diff(steps))) <= manoeuvre["j_max"] * 0.1 * (1 + 1e-12)
    assert a.min() < -0.5 * manoeuvre["d_max"]                # the hard stop did brake hard
    assert np.max(np.abs(_sig(run, "planner.lateral_offset"))) < 0.05
    assert np.max(np.abs(_sig(run, "controller.yc_cg"))) < 0.05


def test_inproc_and_zenoh_give_identical_signals(inproc_run, tmp_path):
    zenoh = _run(tmp_path / "zenoh", "zenoh")
    assert (zenoh / "signals.csv").read_bytes() == (inproc_run / "signals.csv").read_bytes()
    for array in sorted((inproc_run / "arrays").iterdir()):
        assert (zenoh / "arrays" / array.name).read_bytes() == array.read_bytes()
