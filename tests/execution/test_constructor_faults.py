"""`cosim run` with a Python component whose constructor crashes, exits or never returns.

In the master's process (`--transport inproc`, or `--place NAME=inproc` over Zenoh)
the supervisor watches the constructor as a call whose deadline is the start-up
timeout, and completes the run folder (a manifest written before the first
constructor) when it kills or hangs the master. In a process of its own the
handshake's wait has the same timeout. Either way: one line naming the component,
no traceback, a failed manifest, no process left behind.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from tests.execution.test_fmu_faults import COSIM, run_cosim
from tests.helpers.paths import REPO_ROOT

SCENARIO = """\
name: constructor
duration: 0.4
tick: 0.01
components:
  plant:
    python: tests.helpers.components:{cls}
    parameters: {parameters}
sources:
  ref: {{kind: constant, value: 1.0}}
connections:
  - ref.value -> plant.u
"""
BUILT_HERE = {"inproc": ("--transport", "inproc"),
              "placed-inproc": ("--transport", "zenoh", "--place", "plant=inproc")}


def _failed(done, out, left, message: str, cause: dict) -> None:
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last == f"run failed: component 'plant' failed during initialization (t=0 s): {message}"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and last == f"run failed: {manifest['error']}"
    assert manifest["completed_by"] == "supervisor" and manifest["ticks"] == 0
    assert manifest["scenario"]["components"]["plant"]["python"].endswith(":" + cause.pop("cls"))
    assert {k: manifest["cause"][k] for k in cause} == cause
    assert left == []


@pytest.mark.timeout(120)
@pytest.mark.parametrize("where", BUILT_HERE)
def test_a_constructor_past_the_startup_timeout_is_ended_by_the_supervisor(tmp_path, where):
    text = SCENARIO.format(cls="ConstructorFault", parameters="{mode: hang}")
    done, out, left = run_cosim(tmp_path, text, *BUILT_HERE[where], "--startup-timeout", "1")
    _failed(done, out, left, "no return from its constructor within the deadline of 1 s "
                             "(the master process was ended)",
            {"cls": "ConstructorFault", "kind": "deadline", "deadline_s": 1.0,
             "component": "plant", "call": "constructor", "tick": None, "time": 0.0})


@pytest.mark.timeout(120)
@pytest.mark.parametrize("cls, parameters, message, cause", [
    ("ConstructorFault", "{mode: segfault}", "the master process was killed by SIGSEGV in its constructor",
     {"kind": "signal", "signal": "SIGSEGV"}),
    ("ExitsInInit", "{code: 3}", "the master process exited with status 3 in its constructor",
     {"kind": "exit", "exit_code": 3}),
], ids=["segfault", "exit"])
def test_a_constructor_that_ends_the_master_is_reported_by_the_supervisor(
        tmp_path, cls, parameters, message, cause):
    done, out, left = run_cosim(tmp_path, SCENARIO.format(cls=cls, parameters=parameters),
                                "--transport", "inproc")
    _failed(done, out, left, message, {"cls": cls, **cause, "component": "plant",
                                       "call": "constructor", "tick": None})


@pytest.mark.timeout(120)
@pytest.mark.parametrize("cls, parameters, cause", [
    ("ConstructorFault", "{mode: hang}", "no handshake within 1 s after its process started"),
    ("ExitsInInit", "{code: 3}", "process exited with code 3 before its handshake"),
], ids=["hang", "exit"])
def test_a_constructor_fault_in_its_own_process_is_a_failed_run(tmp_path, cls, parameters, cause):
    """Exit 1 and "run failed:", as the same fault in the master's process (a fault of the
    run, not of its input: cosim.errors.StartFault)."""
    text = SCENARIO.format(cls=cls, parameters=parameters)
    done, out, left = run_cosim(tmp_path, text, "--startup-timeout", "1")
    assert done.returncode == 1, done.stderr
    line = f"component 'plant' failed during initialization (t=0 s): {cause}"
    assert done.stderr.strip().splitlines()[-1] == f"run failed: {line}"
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["status"], manifest["error"]) == ("failed", line)
    assert left == []


@pytest.mark.parametrize("option, value", [("--deadline", "nan"), ("--deadline", "-1"),
                                           ("--startup-timeout", "0"), ("--startup-timeout", "inf")])
def test_a_deadline_or_startup_timeout_must_be_a_positive_number(tmp_path, option, value):
    text = SCENARIO.format(cls="Echo", parameters="{}")
    done, out, _ = run_cosim(tmp_path, text, "--transport", "inproc", option, value)
    assert done.returncode == 2
    assert done.stderr.strip() == (f"error: {option} must be a positive number of seconds, "
                                   f"got {float(value)!r}")
    assert not out.exists()


@pytest.mark.timeout(120)
def test_ctrl_c_in_a_constructor_names_it(tmp_path):
    scenario, out = tmp_path / "s.yaml", tmp_path / "run"
    scenario.write_text(SCENARIO.format(cls="ConstructorFault", parameters="{mode: hang}"))
    proc = subprocess.Popen([str(COSIM), "run", str(scenario), "--out", str(out), "--no-figures",
                             "--transport", "inproc"], cwd=REPO_ROOT,
                            env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    end = time.monotonic() + 60
    while not (out / "manifest.json").exists():  # the pending manifest: the constructor is next
        assert time.monotonic() < end and proc.poll() is None, "no pending manifest"
        time.sleep(0.02)
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C does
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 1, stderr
    line = "interrupted before tick 0 (in the constructor of component 'plant')"
    assert stderr.strip().splitlines()[-1] == f"run failed: {line}"
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["status"], manifest["error"]) == ("failed", line)
