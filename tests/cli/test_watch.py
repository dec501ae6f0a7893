"""`cosim watch`: name selection, line format, target resolution, and a real run
watched from a second process through the command line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from cosim.cli.app import main
from cosim.cli.watch import format_line, resolve_target, select_names
from cosim.errors import UserError
from cosim.results.recorder import read_signals
from tests.helpers.components import GOOD
from tests.helpers.paths import REPO_ROOT

ROOT = REPO_ROOT
NAMES = ["vehicle.x", "vehicle.y", "vehicle.vx", "controller.delta", "planner.v_ref"]


def test_select_names_keeps_the_run_order_and_accepts_lists():
    assert select_names(NAMES, []) == NAMES
    assert select_names(NAMES, ["vehicle.[xy]"]) == ["vehicle.x", "vehicle.y"]
    assert select_names(NAMES, ["planner.*,vehicle.vx", "controller.d*"]) == [
        "vehicle.vx", "controller.delta", "planner.v_ref"]
    assert select_names(NAMES, ["nothing.*"]) == []


def test_format_line_is_compact_and_six_digits():
    values = {"a.x": 1 / 3, "a.y": -2.0, "b.z": 12345678.0}
    assert format_line(7, 0.07, values, ["a.x", "b.z"]) == \
        "tick 7  t=0.07  a.x=0.333333  b.z=1.23457e+07"
    assert format_line(1, 0.5, values, ["a.y"], run_id="r1") == "[r1]  tick 1  t=0.5  a.y=-2"


def test_resolve_target_from_a_running_run_folder(tmp_path):
    live = {"run_id": "abc123", "endpoint": "tcp/127.0.0.1:7000"}
    (tmp_path / "manifest.json").write_text(json.dumps({"status": "running", "live": live}))
    assert resolve_target(str(tmp_path), None) == ("abc123", "tcp/127.0.0.1:7000")
    assert resolve_target(str(tmp_path), "tcp/10.0.0.2:7000") == ("abc123", "tcp/10.0.0.2:7000")
    assert resolve_target("r-1.x", "tcp/h:1") == ("r-1.x", "tcp/h:1")
    assert resolve_target("*", "tcp/h:1") == ("*", "tcp/h:1")


@pytest.mark.parametrize("manifest, message", [
    (None, "cannot read the run's manifest"),
    ({"status": "ok", "live": {"run_id": "r", "endpoint": "tcp/h:1"}},
     "run r has already ended (status 'ok')"),
    ({"status": "running", "transport": "inproc"}, "the run has no live view"),
])
def test_resolve_target_errors_name_the_manifest(tmp_path, manifest, message):
    if manifest is not None:
        (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(UserError, match="manifest.json: ") as info:
        resolve_target(str(tmp_path), None)
    assert message in str(info.value)


def test_watch_command_user_errors_exit_2(capsys):
    assert main(["watch", "some-run"]) == 2
    assert "needs --connect ENDPOINT" in capsys.readouterr().err
    assert main(["watch", "a/b", "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "run id 'a/b' must be non-empty" in capsys.readouterr().err
    assert main(["watch", "r", "--connect", "tcp/127.0.0.1:1", "--every", "0"]) == 2
    assert "--every must be >= 1" in capsys.readouterr().err


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


@pytest.mark.integration
@pytest.mark.timeout(120)
def test_watching_a_run_from_a_second_process_prints_the_recorded_values(tmp_path):
    scenario = tmp_path / "gain.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "run"
    # paced at real time and long enough for a watcher started on a busy machine; ended
    # by Ctrl-C once the watcher has its lines (the interrupted run keeps every tick)
    run = subprocess.Popen([sys.executable, "-m", "cosim.cli.app", "run", str(scenario), "--out",
                            str(out), "--no-figures", "--set", "duration=60.0", "--realtime", "1"],
                           cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, text=True,
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        lines = [run.stdout.readline(), run.stdout.readline()]
        assert lines[0] == f"run folder: {out}\n"
        run_id, endpoint = lines[1].split()[2], lines[1].split()[4]
        watcher = subprocess.run(
            [sys.executable, "-m", "cosim.cli.app", "watch", str(out), "--signals", "gain.*",
             "--every", "20", "--count", "4"],
            cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=60)
        run.send_signal(signal.SIGINT)
        assert run.wait(timeout=60) == 1  # interrupted: the run folder holds what it did
    finally:
        if run.poll() is None:  # a failure above: end the run as a user would, not by SIGKILL
            run.send_signal(signal.SIGINT)  # (the master and its processes would outlive it)
            try:
                run.wait(timeout=30)
            except subprocess.TimeoutExpired:
                run.kill()
    assert watcher.returncode == 0, watcher.stderr
    assert f"watching run {run_id} at {endpoint}" in watcher.stderr
    assert "ended" not in watcher.stderr  # it stopped after --count lines
    live = json.loads((out / "manifest.json").read_text())["live"]
    assert live == {"run_id": run_id, "endpoint": endpoint}
    assert (out / "live.credential").stat().st_mode & 0o777 == 0o600  # the watcher's key
    names, data = read_signals(out / "signals.csv")
    printed = watcher.stdout.splitlines()
    assert len(printed) == 4
    ticks = [int(line.split()[1]) for line in printed]
    assert all(k % 20 == 0 for k in ticks) and ticks == sorted(set(ticks))
    assert ticks[-1] - ticks[0] == 60  # consecutive multiples of 20: nothing skipped
    for tick, line in zip(ticks, printed):
        row = data[tick]
        assert line == format_line(tick, row[0], {"gain.y": row[names.index("gain.y")]},
                                   ["gain.y"])


@pytest.mark.integration
@pytest.mark.timeout(180)
def test_watch_with_deploy_follows_a_tls_run_and_without_it_says_it_cannot_connect(tmp_path):
    certs = tmp_path / "certs"
    subprocess.run(["sh", str(ROOT / "examples" / "tls" / "make_certs.sh"), str(certs), "node",
                    "127.0.0.1"], check=True, capture_output=True)
    tls = ("tls:\n  root_ca_certificate: certs/ca.pem\n  certificate: certs/node.pem\n"
           "  private_key: certs/node-key.pem\n")
    (tmp_path / "master.yaml").write_text("listen: [tls/127.0.0.1:0]\n" + tls)
    (tmp_path / "watch.yaml").write_text(tls)
    scenario = tmp_path / "gain.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "run"
    run = subprocess.Popen([sys.executable, "-m", "cosim.cli.app", "run", str(scenario), "--out",
                            str(out), "--no-figures", "--set", "duration=20.0", "--realtime", "1",
                            "--deploy", str(tmp_path / "master.yaml")],
                           cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert run.stdout.readline() == f"run folder: {out}\n"
        endpoint = run.stdout.readline().split()[4]
        assert endpoint.startswith("tls/127.0.0.1:")
        watcher = subprocess.run(
            [sys.executable, "-m", "cosim.cli.app", "watch", str(out), "--deploy",
             str(tmp_path / "watch.yaml"), "--signals", "gain.y", "--every", "10", "--count", "3"],
            cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=60)
        refused = subprocess.run([sys.executable, "-m", "cosim.cli.app", "watch", str(out)],
                                 cwd=tmp_path, env=_env(), capture_output=True, text=True,
                                 timeout=60)
        assert run.wait(timeout=90) == 0
    finally:
        run.kill()
    assert refused.returncode == 2
    assert f"cannot open a session with {endpoint} within" in refused.stderr
    assert watcher.returncode == 0, watcher.stderr
    names, data = read_signals(out / "signals.csv")
    printed = watcher.stdout.splitlines()
    assert len(printed) == 3
    for line in printed:
        tick = int(line.split()[1])
        assert line == format_line(tick, data[tick][0], {"gain.y": data[tick][names.index("gain.y")]},
                                   ["gain.y"])
