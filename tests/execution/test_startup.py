"""Run assembly start-up: the clock, the marks in manifest.json, the order of the
start-up steps, lazy loading before the spawn, and the live observer's cost."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.cli.app import main
from cosim.component import Component, Port
from cosim.errors import UserError
from cosim.transport.inproc import InprocComponent, describe_exception, import_component_class
from cosim.transport.launch import PythonComponentLaunch
from cosim.engine.master import Master
from cosim.execution.prepare import plan_launches
from cosim.execution.run import _LivePublisher
from cosim.scenario.loader import SOURCE_CLASSES, load_scenario
from cosim.engine.startup import StartupClock, process_age_s
from tests.helpers.components import GOOD
from tests.helpers.paths import REPO_ROOT

ROOT = REPO_ROOT


def test_process_age_of_a_child_lies_between_two_readings_of_our_clock():
    before = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        after_start = time.perf_counter()
        time.sleep(0.3)
        age = process_age_s(child.pid)
        now = time.perf_counter()
    finally:
        child.kill()
        child.wait()
    resolution = 0.02  # /proc start times count clock ticks of 10 ms
    assert now - after_start - resolution <= age <= now - before + resolution


def test_process_age_of_no_process_is_none():
    assert process_age_s(2 ** 22 + 12345) is None  # above the kernel's pid_max


def test_clock_marks_are_seconds_since_its_origin():
    clock = StartupClock(100.0, "test origin")
    assert clock.mark("a", at=100.25) == 0.25
    assert clock.mark("b", at=101.5) == 1.5
    marks = clock.as_dict()
    cpu = marks.pop("cpu_s")
    assert marks == {"origin": "test origin", "a_s": 0.25, "b_s": 1.5}
    assert list(cpu) == ["a", "b"] and 0 < cpu["a"] <= cpu["b"] <= time.process_time()
    started = StartupClock.from_process_start()
    assert started.origin_kind == "process start"
    assert 0 < started.mark("now") < time.perf_counter()


def test_a_forked_clock_counts_the_parent_cpu_time_before_the_fork():
    clock = StartupClock(time.perf_counter(), "test origin")
    clock.mark("before")
    clock.after_fork(1000.0)  # as if the parent had used 1000 s of CPU before forking this one
    clock.mark("after")
    assert 1000.0 + clock.cpu["before"] <= clock.cpu["after"] <= 1000.0 + time.process_time()


def test_component_processes_load_no_pydantic_for_the_shipped_classes():
    code = ("import sys, cosim.transport.zenoh.runner, controllers.backstepping, controllers.planning, "
            "controllers.baselines, cosim.sources\n"
            "print(sorted(m for m in ('pydantic', 'rich', 'typer', 'yaml') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_model_reference_reads_as_the_parameters_model():
    from controllers.backstepping import BacksteppingController
    from controllers.backstepping.parameters import BacksteppingParameters
    from controllers.baseline_parameters import SpeedLoopParameters
    from controllers.baselines import SpeedLoop

    assert BacksteppingController.parameters_model is BacksteppingParameters
    assert SpeedLoop().parameters_model is SpeedLoopParameters


def test_the_run_path_loads_no_numpy_or_fmpy_before_the_spawn():
    code = ("import sys, cosim.cli.app, cosim.execution.run, cosim.scenario.loader, cosim.distributed.placement, "
            "cosim.transport.zenoh.host, cosim.transport.zenoh.processes\n"
            "print(sorted(m for m in ('numpy', 'fmpy', 'cosim.component', 'matplotlib') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout
    assert out.strip() == "[]"


SPAWN_PROBE = """
import sys
from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario
seen = []
run_scenario(load_scenario(sys.argv[1]), sys.argv[2], "zenoh", progress=False,
             on_live=lambda run_id, endpoint: seen.append(sorted(
                 m for m in ("numpy", "fmpy", "cosim.component") if m in sys.modules)))
print(seen)
"""


def test_a_zenoh_run_spawns_its_processes_before_loading_numpy(tmp_path):
    path = _scenario(tmp_path, GOOD.replace("{k: 3.0}", "{k: 3.0}\n    period: 0.01"))
    out = subprocess.run([sys.executable, "-c", SPAWN_PROBE, str(path), str(tmp_path / "run")],
                         cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[[]]"  # on_live runs right after the spawn


def _scenario(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def test_plan_launches_imports_a_class_only_when_its_period_is_needed(tmp_path):
    text = GOOD.replace("tests.helpers.components:Gain", "no_such_module_here:Gain")
    scenario = load_scenario(_scenario(tmp_path, text))
    with pytest.raises(UserError, match="component 'gain': cannot import module "
                                        "'no_such_module_here'"):
        plan_launches(scenario)  # no period given: the class's default is needed
    text = text.replace("{k: 3.0}", "{k: 3.0}\n    period: 0.02")
    scenario = load_scenario(_scenario(tmp_path, text))
    launches = plan_launches(scenario, import_classes=False)
    roots = (str(tmp_path), os.getcwd())  # the scenario's folder, then the cwd
    assert launches[0] == PythonComponentLaunch("gain", "no_such_module_here:Gain", {"k": 3.0}, 2,
                                                roots, steps=25)  # 50 ticks, every second one
    assert [l.name for l in launches] == ["gain", "ramp"] and launches[1].period_ticks == 1


def test_platform_sources_declare_no_default_period():
    # plan_launches relies on it to skip importing source classes before the spawn
    for kind, class_path in SOURCE_CLASSES.items():
        assert import_component_class(class_path, kind).default_period is None


def test_a_missing_class_over_zenoh_reads_as_before_the_spawn(tmp_path, capsys):
    text = GOOD.replace("tests.helpers.components:Gain", "no_such_module_here:Gain").replace(
        "{k: 3.0}", "{k: 3.0}\n    period: 0.01")
    path = _scenario(tmp_path, text)
    for transport in ("inproc", "zenoh"):
        assert main(["run", str(path), "--out", str(tmp_path / transport), "--no-figures",
                     "--transport", transport]) == 2
        err = capsys.readouterr().err
        assert "component 'gain': cannot import module 'no_such_module_here'" in err
        assert "Traceback" not in err


@pytest.mark.integration
def test_start_up_marks_in_the_manifest_are_in_order(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(REPO_ROOT))  # component processes import test_cli
    path = _scenario(tmp_path, GOOD)
    for transport in ("inproc", "zenoh"):
        out = tmp_path / transport
        assert main(["run", str(path), "--out", str(out), "--no-figures",
                     "--transport", transport]) == 0
        manifest = json.loads((out / "manifest.json").read_text())
        marks = manifest["startup"]
        assert marks["origin"] == "process start"
        assert manifest["time_to_tick0_s"] == marks["tick0_s"]
        steps = ["scenario_loaded_s", "fmus_ready_s", "components_ready_s", "tick0_s"]
        if transport == "zenoh":
            steps.insert(1, "spawned_s")
            processes = manifest["startup_processes_s"]
            assert sorted(processes) == ["gain", "ramp"]
            for ages in processes.values():
                order = [ages[k] for k in ("imported", "spec", "session", "built", "ready")]
                assert order == sorted(order) and order[0] > 0 and ages["cpu"] > 0
        values = [marks[k] for k in steps]
        assert values == sorted(values) and values[0] > 0
        cpu = [marks["cpu_s"][k[:-2]] for k in steps]
        assert cpu == sorted(cpu) and cpu[0] > 0


class Counter(Component):
    """Two scalar outputs and an array: the live vector holds the scalars only."""

    outputs = (Port("n"), Port("w", size=2), Port("half"))

    def step(self, t, inputs):
        return {"n": t * 100, "w": np.array([t, -t]), "half": t * 50}


class _FakeLive:
    def __init__(self, matching_from: int) -> None:
        self.matching_from = matching_from
        self.matching = False
        self.published: list = []

    def publish(self, tick, t, names, values):
        self.published.append((tick, t, list(names), values.tolist()))


class _Toggle:
    """Observer that turns the fake's `matching` on from a given tick."""

    def __init__(self, live: _FakeLive) -> None:
        self.live = live

    def begin(self, master):
        pass

    def after_tick(self, tick, t, values, arrays):
        self.live.matching = tick >= self.live.matching_from  # seen by the next observer


def test_live_observer_builds_vectors_only_while_watched():
    live = _FakeLive(matching_from=3)
    counter = InprocComponent(PythonComponentLaunch("c", "tests.execution.test_startup:Counter"))
    master = Master({"c": counter}, [], 0.01, 5, 0.0, [_Toggle(live), _LivePublisher(live)])
    master.run()
    assert live.published == [(k, k * 0.01, ["c.n", "c.half"], [k * 0.01 * 100, k * 0.01 * 50])
                              for k in (3, 4, 5)]


def test_describe_exception_is_public_and_one_line():
    assert describe_exception(ZeroDivisionError("x by zero")) == "ZeroDivisionError: x by zero"


def test_loop_time_is_the_part_of_the_run_after_tick0(tmp_path):
    from cosim.execution.run import run_scenario

    result = run_scenario(load_scenario(_scenario(tmp_path, GOOD)), tmp_path / "ok", progress=False)
    assert result.status == "ok" and 0 < result.loop_time_s <= result.wall_time_s
    failing = GOOD.replace("{k: 3.0}", "{k: 3.0, raise_at: 0.0}")  # fails in the initialization
    result = run_scenario(load_scenario(_scenario(tmp_path, failing)), tmp_path / "failed",
                          progress=False)
    assert result.status == "failed" and result.ticks == 0 and result.loop_time_s is None
