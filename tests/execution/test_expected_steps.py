"""A component's host tells its constructor the steps its process will ask of it
(`cosim.component.expected_steps`): a component process and the `cosim run` command
always (their process hosts one run), a Python session never (it may run again)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import cosim
from cosim.component import constructing_for, expected_steps
from cosim.transport.inproc import PythonComponentLaunch, construct_component
from tests.helpers.components import launch
from tests.helpers.paths import REPO_ROOT

SCENARIO = """\
name: steps_seen
duration: 1.0
tick: 0.01
components:
  seen:
    python: tests.helpers.components:StepsSeen
    period: 0.02
"""


def test_outside_a_construction_nothing_is_expected():
    assert expected_steps() is None
    with constructing_for(7):
        assert expected_steps() == 7
    assert expected_steps() is None


def test_the_in_process_host_passes_the_launchs_steps():
    assert construct_component(launch("seen", "StepsSeen")).seen == -1.0
    told = PythonComponentLaunch("seen", "tests.helpers.components:StepsSeen", steps=321)
    assert construct_component(told).seen == 321.0


@pytest.mark.integration
@pytest.mark.parametrize("transport, expected", [("zenoh", 50.0), ("inproc", -1.0)])
def test_a_component_process_is_told_its_steps_a_python_session_is_not(
        tmp_path, transport, expected):
    import yaml

    run = cosim.run(yaml.safe_load(SCENARIO), transport=transport, out=tmp_path / "run")
    assert run.status == "ok"
    assert set(run.signals["seen.steps"]) == {expected}  # 100 ticks, every 2nd: 50 steps


@pytest.mark.integration
def test_the_cosim_run_command_tells_its_own_components(tmp_path):
    scenario = tmp_path / "steps_seen.yaml"
    scenario.write_text(SCENARIO)
    done = subprocess.run([sys.executable, "-m", "cosim.cli.app", "run", str(scenario),
                           "--transport", "inproc", "--no-figures", "--out", str(tmp_path / "run")],
                          cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = (tmp_path / "run" / "signals.csv").read_text().splitlines()
    column = lines[0].split(",").index("seen.steps")
    assert {line.split(",")[column] for line in lines[1:]} == {"50.0"}


@pytest.mark.integration
@pytest.mark.parametrize("runs", [3, np.int64(3)])  # a sweep's samples may come from numpy
def test_a_session_told_how_many_runs_its_process_hosts_tells_its_components(tmp_path, runs):
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    scenario = tmp_path / "steps_seen.yaml"
    scenario.write_text(SCENARIO)
    result = run_scenario(load_scenario(scenario), out_dir=tmp_path / "run", transport="inproc",
                          progress=False, runs_in_process=runs)
    assert result.status == "ok"
    assert set(result.full_signals[1][:, result.full_signals[0].index("seen.steps")]) == {150.0}


def _steps_seen_by_sweep_samples(tmp_path, **options) -> set[float]:
    import numpy as np

    from cosim.execution.sweep import run_sweep

    scenario = tmp_path / "steps_seen.yaml"
    scenario.write_text(SCENARIO)
    result = run_sweep(scenario, ["duration=1.0:1.0"], 2, out_dir=tmp_path / "sweep", **options)
    assert not result.failures, result.failures
    seen = set()
    for folder in sorted((tmp_path / "sweep" / "samples").iterdir()):
        lines = (folder / "signals.csv").read_text().splitlines()
        column = lines[0].split(",").index("seen.steps")
        seen |= set(np.array([float(line.split(",")[column]) for line in lines[1:]]))
    return seen


@pytest.mark.integration
def test_a_sweeps_own_worker_processes_are_told_the_steps_of_every_sample(tmp_path):
    # 2 samples of 50 steps: a worker process of the sweep's own cluster runs at most both
    assert _steps_seen_by_sweep_samples(tmp_path) == {100.0}


@pytest.mark.integration
def test_sweep_workers_in_this_process_are_not_told(tmp_path):
    # threads of the caller's process, which may run again
    assert _steps_seen_by_sweep_samples(tmp_path, cluster_options={"processes": False}) == {-1.0}


@pytest.mark.integration
def test_workers_of_a_joined_cluster_are_not_told(tmp_path):
    # a cluster given by its scheduler's address outlives the sweep: its workers may run again
    from cosim.execution.sweep import local_cluster

    with local_cluster(1) as cluster:
        assert _steps_seen_by_sweep_samples(tmp_path, scheduler=cluster.scheduler_address) == {-1.0}


@pytest.mark.parametrize("runs", [0, -2, 1.5, True, "3"])
def test_a_count_of_runs_below_one_or_not_whole_is_refused(tmp_path, runs):
    from cosim.errors import UserError
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    scenario = tmp_path / "steps_seen.yaml"
    scenario.write_text(SCENARIO)
    with pytest.raises(UserError, match="runs_in_process must be a whole number from 1 up"):
        run_scenario(load_scenario(scenario), out_dir=tmp_path / "run", transport="inproc",
                     progress=False, runs_in_process=runs)
    assert not (tmp_path / "run").exists()
