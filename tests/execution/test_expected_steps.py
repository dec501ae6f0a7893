"""A component's host tells its constructor the steps its process will ask of it
(`cosim.component.expected_steps`): a component process and the `cosim run` command
always (their process hosts one run), a Python session never (it may run again)."""

from __future__ import annotations

import subprocess
import sys

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
