"""`--place NAME=inproc` (or `host: inproc`): a Python component in the master's own process.

Over Zenoh the others keep their processes; the signals are the same bytes
as with every component in its own process, and the manifest's pids say who
ran where. An FMU cannot be placed there, and `inproc` is never a worker.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

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


def test_cli_with_host_inproc_in_the_file_uses_the_prestarted_processes_of_the_others(tmp_path):
    text = LANE_CHANGE.read_text().replace("    python: controllers.planning:Planner\n",
                                           "    python: controllers.planning:Planner\n    host: inproc\n")
    assert "host: inproc" in text
    scenario = tmp_path / "lane_change_planner_inproc.yaml"
    scenario.write_text(text)
    runs = {}
    for name, path in (("mixed", scenario), ("own", LANE_CHANGE)):
        done = subprocess.run([sys.executable, "-m", "cosim.cli.app", "run", str(path), "--set", "duration=4",
                               "--no-figures", "--out", str(tmp_path / name)],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        runs[name] = tmp_path / name
    assert (runs["mixed"] / "signals.csv").read_bytes() == (runs["own"] / "signals.csv").read_bytes()
    manifest = json.loads((runs["mixed"] / "manifest.json").read_text())
    assert manifest["pids"]["planner"] == manifest["pids"]["vehicle"] != manifest["pids"]["controller"]
    assert set(manifest["startup_processes_s"]) == {"controller"}


@pytest.mark.parametrize("name", ["inproc", "local"])
def test_a_worker_cannot_take_a_reserved_host_name(name):
    from cosim.distributed.worker import Worker

    with pytest.raises(ValueError, match=rf"worker name '{name}' is reserved: host: {name}"):
        Worker(name)
