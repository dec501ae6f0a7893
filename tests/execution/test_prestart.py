"""Component processes started while `cosim run` loads the scenario: which are
started, that the run uses exactly those, and that none is ever left behind."""

from __future__ import annotations

import json
import os
import time

import pytest

import cosim.execution.prestart
from cosim.cli.app import main
from cosim.component import Component, Port
from cosim.execution.prestart import local_python_components, local_python_names, prestart_components
from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario
from tests.helpers.components import GOOD
from tests.helpers.paths import REPO_ROOT


pytestmark = pytest.mark.integration


@pytest.fixture(autouse=True)
def child_can_import_test_components(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(REPO_ROOT))


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def _runner_cmdline(pid: int, bound_s: float = 30.0) -> list[bytes]:
    """The process's argv once it shows the runner's (under load, just after the spawn,
    /proc may still show the parent's); polled, at most `bound_s`, then the last seen."""
    stop = time.monotonic() + bound_s
    while True:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
        if b"cosim.transport.zenoh.runner" in argv or time.monotonic() > stop:
            return argv
        time.sleep(0.01)


class Weighted(Component):
    """y = x * sum(weights): a component with a large parameter."""

    inputs = (Port("x"),)
    outputs = (Port("y"),)

    def __init__(self, weights):
        self.total = float(sum(weights))

    def step(self, t, inputs):
        return {"y": inputs["x"] * self.total}


def test_a_spec_larger_than_a_pipe_reaches_its_process(tmp_path):
    weights = [i / 7 for i in range(20000)]  # about 400 kB of JSON
    path = tmp_path / "big.yaml"
    path.write_text(GOOD.replace("tests.helpers.components:Gain", "tests.execution.test_prestart:Weighted")
                    .replace("{k: 3.0}", "{weights: " + json.dumps(weights) + "}")
                    .replace("duration: 0.5", "duration: 0.05"))
    early = prestart_components(path)
    scenario = load_scenario(path)
    result = run_scenario(scenario, tmp_path / "z", "zenoh", progress=False, prestart=early)
    reference = run_scenario(scenario, tmp_path / "i", "inproc", progress=False)
    assert result.status == "ok"
    assert result.signals.read_bytes() == reference.signals.read_bytes()


def test_local_python_names_from_a_raw_document():
    document = {"components": {"vehicle": {"fmu": "Bicycle"},
                               "controller": {"python": "a:B"},
                               "far": {"python": "a:C", "host": "w1"},
                               "near": {"python": "a:D", "host": "local"},
                               "odd": "not a mapping"},
                "sources": {"gust": {"kind": "step"}, "elsewhere": {"kind": "ramp", "host": "w2"}}}
    assert local_python_names(document) == ["controller", "near", "gust"]
    assert local_python_components(document) == {"controller": "a", "near": "a",
                                                  "gust": "cosim.sources"}
    assert local_python_components({"components": {"c": {"python": 3}}}) == {"c": None}
    assert local_python_names(["a list"]) == [] and local_python_names({"components": 3}) == []


def test_unreadable_or_componentless_files_start_nothing(tmp_path):
    assert prestart_components(tmp_path / "missing.yaml") is None
    bad = tmp_path / "bad.yaml"
    bad.write_text("components: [unclosed")
    assert prestart_components(bad) is None
    fmu_only = tmp_path / "fmu.yaml"
    fmu_only.write_text("components:\n  vehicle: {fmu: Bicycle}\n")
    assert prestart_components(fmu_only) is None


def test_the_run_uses_the_prestarted_processes_and_matches_inproc(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    early = prestart_components(path)
    assert sorted(early.children) == ["gain", "ramp"]
    pids = {name: child.pid for name, child in early.children.items()}
    argv = _runner_cmdline(pids["gain"])
    assert argv[argv.index(b"--name") + 1] == b"gain" and b"--spec-stdin" in argv
    assert argv[argv.index(b"--preload") + 1] == b"tests.helpers.components"
    scenario = load_scenario(path)
    result = run_scenario(scenario, tmp_path / "z", "zenoh", progress=False, prestart=early)
    assert result.status == "ok"
    manifest = json.loads(result.manifest.read_text())
    assert manifest["run_id"] == early.run_id and manifest["live"]["endpoint"] == early.endpoint
    assert {n: manifest["pids"][n] for n in pids} == pids
    assert all(_gone(pid) for pid in pids.values())
    reference = run_scenario(scenario, tmp_path / "i", "inproc", progress=False)
    assert result.signals.read_bytes() == reference.signals.read_bytes()


def test_processes_an_inproc_run_does_not_use_are_ended(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    early = prestart_components(path)
    pids = [child.pid for child in early.children.values()]
    result = run_scenario(load_scenario(path), tmp_path / "i", "inproc", progress=False,
                          prestart=early)
    assert result.status == "ok" and all(_gone(pid) for pid in pids)


def test_a_prestarted_process_whose_stdin_closes_exits_by_itself(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    early = prestart_components(path)
    try:
        for child in early.children.values():
            child.popen.stdin.close()
        assert [child.popen.wait(timeout=30) for child in early.children.values()] == [0, 0]
    finally:
        early.close()


def test_a_scenario_error_ends_the_prestarted_processes(tmp_path, monkeypatch, capsys):
    started = []

    def recording(path):
        early = prestart_components(path)
        started.append(early)
        return early

    monkeypatch.setattr(cosim.execution.prestart, "prestart_components", recording)
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("tick: 0.01", "tick: 0.01\ncolour: red"))
    assert main(["run", str(bad), "--out", str(tmp_path / "run")]) == 2
    assert "colour" in capsys.readouterr().err
    assert len(started) == 1 and sorted(started[0].children) == ["gain", "ramp"]
    assert all(_gone(child.pid) for child in started[0].children.values())
