"""Same scenario, both transports: bit-identical run folders; failures over Zenoh.

Each Zenoh run spawns one OS process per Python component, so these tests
take a few seconds each.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.component import Component, Port
from cosim.results.recorder import read_signals
from tests.helpers.components import GOOD
from tests.helpers.fmus import LAG_SCENARIO
from tests.helpers.paths import REPO_ROOT


pytestmark = pytest.mark.integration


class Doomed(Component):
    """Passes x through; its process kills itself with SIGKILL at t == die_at."""

    inputs = (Port("x"),)
    outputs = (Port("y"),)

    def __init__(self, die_at: float):
        self.die_at = die_at

    def step(self, t, inputs):
        if t == self.die_at:
            os.kill(os.getpid(), signal.SIGKILL)
        return {"y": inputs["x"]}


@pytest.fixture(autouse=True)
def child_can_import_test_components(monkeypatch):
    """Component processes import the test classes from tests/ (tests.helpers.components, this module)."""
    monkeypatch.setenv("PYTHONPATH", str(REPO_ROOT))


def _run(scenario: Path, out: Path, transport: str, *extra: str) -> int:
    return main(["run", str(scenario), "--out", str(out), "--transport", transport,
                 "--no-figures", *extra])


def test_inproc_and_zenoh_give_identical_files(tmp_path, lag_fmus):
    scenario = tmp_path / "lag.yaml"
    scenario.write_text(LAG_SCENARIO.format(fmu=lag_fmus[2]))
    for transport in ("inproc", "zenoh"):
        assert _run(scenario, tmp_path / transport, transport) == 0
    inproc, zenoh = (tmp_path / "inproc" / "signals.csv"), (tmp_path / "zenoh" / "signals.csv")
    assert inproc.read_bytes() == zenoh.read_bytes()
    assert len(read_signals(zenoh)[1]) == 101
    metrics = [json.loads((tmp_path / t / "metrics.json").read_text()) for t in ("inproc", "zenoh")]
    assert metrics[0] == metrics[1] and metrics[0]["controller.steps"] == 51.0
    manifest = json.loads((tmp_path / "zenoh" / "manifest.json").read_text())
    assert manifest["transport"] == "zenoh" and manifest["status"] == "ok"
    assert manifest["live"]["run_id"] == manifest["run_id"]
    assert manifest["live"]["endpoint"].startswith("tcp/")


LANE_SCENARIO = """\
name: lane_demo
duration: 0.5
tick: 0.01
components:
  mixer:
    python: tests.helpers.components:Mixer
    parameters: {gain: 0.5}
  track:
    python: tests.helpers.components:Tracker
    parameters: {k: 0.7}
sources:
  ramp: {kind: ramp, start: 0.0, end: 1.0, t_start: 0.0, t_end: 0.5}
connections:
  - {from: ramp.value, to: mixer.u}
  - {from: mixer.y, to: track.x}
  - {from: mixer.z, to: track.ref}
  - {from: ramp.value, to: track.v}
  - {from: mixer.z, to: track.w, delay: 1}
"""


def test_a_component_on_the_values_lane_in_process_gives_the_zenoh_runs_files(tmp_path):
    """In-process the tracker steps on `step_values` (scalar and array inputs), over Zenoh on `step`."""
    scenario = tmp_path / "lane.yaml"
    scenario.write_text(LANE_SCENARIO)
    for transport in ("inproc", "zenoh"):
        assert _run(scenario, tmp_path / transport, transport) == 0
    inproc, zenoh = (tmp_path / "inproc" / "signals.csv"), (tmp_path / "zenoh" / "signals.csv")
    assert inproc.read_bytes() == zenoh.read_bytes()
    names, data = read_signals(inproc)
    assert "track.energy" in names and len(data) == 51
    metrics = [json.loads((tmp_path / t / "metrics.json").read_text()) for t in ("inproc", "zenoh")]
    assert metrics[0] == metrics[1] and metrics[0]["track.steps"] == 51.0


def test_nan_over_zenoh_fails_the_run_with_a_readable_partial_file(tmp_path, capsys):
    scenario = tmp_path / "gain.yaml"
    scenario.write_text(GOOD)
    code = _run(scenario, tmp_path / "z", "zenoh", "--set", "components.gain.parameters.fail_at=0.2")
    assert code == 1
    err = capsys.readouterr().err
    assert "component 'gain' failed at tick 20 (t=0.2 s)" in err and "nan" in err
    _, data = read_signals(tmp_path / "z" / "signals.csv")
    assert data.shape == (20, 3)
    manifest = json.loads((tmp_path / "z" / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["ticks"] == 19


def test_killed_component_process_ends_the_run_with_its_name(tmp_path, capsys):
    scenario = tmp_path / "doomed.yaml"
    scenario.write_text(GOOD.replace("tests.helpers.components:Gain", "tests.transport.test_transports_identical:Doomed")
                        .replace("{k: 3.0}", "{die_at: 0.3}"))
    assert _run(scenario, tmp_path / "z", "zenoh") == 1
    err = capsys.readouterr().err
    assert "component 'gain'" in err and "tick 30" in err
    names, data = read_signals(tmp_path / "z" / "signals.csv")
    assert names == ["time", "gain.y", "ramp.value"] and data.shape == (30, 3)
    manifest = json.loads((tmp_path / "z" / "manifest.json").read_text())
    assert manifest["status"] == "failed" and "gain" in manifest["error"]
    pid = manifest["pids"]["gain"]
    with pytest.raises(ProcessLookupError):  # no process left behind
        os.kill(pid, 0)


def test_live_watcher_sees_the_recorded_values(tmp_path):
    """A watcher started by hand during a run receives rows identical to signals.csv."""
    import threading
    import time

    from cosim.transport.zenoh.auth import LIVE_CREDENTIAL_FILE, read_credential_file
    from cosim.transport.zenoh.live import watch

    scenario = tmp_path / "gain.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "live"
    received: list = []

    def watcher() -> None:
        manifest = out / "manifest.json"
        for _ in range(400):  # wait for the run to announce its live endpoint
            if manifest.is_file() and "live" in json.loads(manifest.read_text()):
                break
            time.sleep(0.05)
        live = json.loads(manifest.read_text())["live"]
        credential = read_credential_file(out / LIVE_CREDENTIAL_FILE)  # owner-only, in the folder
        for tick, t, values in watch(live["run_id"], live["endpoint"], credential):
            received.append((tick, t, values))
            if len(received) >= 5:
                return

    thread = threading.Thread(target=watcher, daemon=True)
    thread.start()
    # 2 s of simulated time paced at real time leaves the watcher time to connect
    assert _run(scenario, out, "zenoh", "--set", "duration=2.0", "--realtime", "1") == 0
    thread.join(timeout=30)
    assert len(received) == 5
    names, data = read_signals(out / "signals.csv")
    for tick, t, values in received:
        assert sorted(values) == sorted(names[1:])
        row = data[tick]
        assert row[0] == t
        assert [values[n] for n in names[1:]] == row[1:].tolist()
