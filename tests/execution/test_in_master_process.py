"""`--place NAME=inproc` (or `host: inproc`): a Python component in the master's own process.

Over Zenoh the others keep their processes; the signals are the same bytes
as with every component in its own process, and the manifest's pids say who
ran where. An FMU cannot be placed there, and `inproc` is never a worker.
"""

from __future__ import annotations

import json
import os

import pytest

from cosim.distributed.placement import in_master_process, resolve_placement
from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import REPO_ROOT

LANE_CHANGE = REPO_ROOT / "scenarios" / "lane_change.yaml"


def test_inproc_is_a_placement_in_the_master_not_a_worker():
    scenario = load_scenario(LANE_CHANGE)
    assert in_master_process(scenario) == set()
    assert in_master_process(scenario, ["planner=inproc"]) == {"planner"}
    assert resolve_placement(scenario, ["planner=inproc", "controller=w1"]) == {"controller": "w1"}
    assert in_master_process(load_scenario(LANE_CHANGE, ["components.planner.host=inproc"])) == {"planner"}
    assert in_master_process(scenario, ["planner=local"]) == set()
    with pytest.raises(UserError, match=r"component 'vehicle': host: 'inproc' puts a Python component in the "
                                        r"master's process; 'vehicle' is an FMU"):
        resolve_placement(scenario, ["vehicle=inproc"])


def test_a_zenoh_run_with_the_planner_in_the_master_gives_the_same_bytes(tmp_path):
    scenario = load_scenario(LANE_CHANGE, ["duration=4"])
    own = run_scenario(scenario, tmp_path / "own", transport="zenoh", progress=False)
    mixed = run_scenario(scenario, tmp_path / "mixed", transport="zenoh", progress=False,
                         place=["planner=inproc"])
    assert own.status == mixed.status == "ok"
    assert (tmp_path / "mixed" / "signals.csv").read_bytes() == (tmp_path / "own" / "signals.csv").read_bytes()
    pids = json.loads((tmp_path / "mixed" / "manifest.json").read_text())["pids"]
    assert pids["planner"] == pids["vehicle"] == os.getpid() != pids["controller"]
    pids = json.loads((tmp_path / "own" / "manifest.json").read_text())["pids"]
    assert len({pids["planner"], pids["controller"], os.getpid()}) == 3
