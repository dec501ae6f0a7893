"""`cosim recover` refuses a run that is still recording, and still recovers one whose
processes were killed: the recorder's lock on the signals spool tells them apart."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from cosim.engine.master import Master
from cosim.errors import UserError
from cosim.results.recorder import Recorder, read_signals
from cosim.results.recover import recover
from tests.helpers.components import GOOD
from tests.helpers.paths import REPO_ROOT
from tests.results.test_recorder import Echo, Noisy, _comp, _edge, _spooled_rows, _wait


class RecoverAt:
    """Observer calling `recover` on the run folder at one tick, keeping what it raised."""

    def __init__(self, folder, tick):
        self.folder, self.tick, self.raised = folder, tick, None

    def begin(self, master):
        pass

    def after_tick(self, tick, t, values, arrays):
        if tick == self.tick:
            with pytest.raises(UserError) as info:
                recover(self.folder)
            self.raised = str(info.value)


def test_recover_refuses_a_folder_while_its_recorder_records(tmp_path):
    probe = RecoverAt(tmp_path, 40)
    recorder = Recorder(tmp_path, flush_interval=0.0)
    comps = {"noisy": _comp("noisy", Noisy, seed=7), "echo": _comp("echo", Echo, 3)}
    master = Master(comps, [_edge("noisy", "u", "echo", "u")], tick=0.01, total_ticks=100,
                    observers=[recorder, probe])
    try:
        master.run()
    finally:
        recorder.close()
    assert probe.raised == (f"run folder {tmp_path} is still being written by a running run "
                            f"(pid {os.getpid()}); recover it after it ends")
    assert read_signals(tmp_path / "signals.csv")[1].shape == (101, 4)  # the run lost nothing
    assert not list(tmp_path.rglob("*.f64*"))


def _cosim(*args, **options):
    return subprocess.run([sys.executable, "-m", "cosim.cli.app", *args], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=120, check=False,
                          **options)


def test_cosim_recover_refuses_a_running_run_then_recovers_it_once_killed(tmp_path):
    scenario = tmp_path / "slow.yaml"
    scenario.write_text(GOOD)  # --set duration=30 below
    out = tmp_path / "run"
    log = (tmp_path / "run.log").open("w")
    run = subprocess.Popen([sys.executable, "-m", "cosim.cli.app", "run", str(scenario),
                            "--out", str(out), "--transport", "inproc", "--realtime", "1",
                            "--set", "duration=30", "--no-figures"],
                           cwd=REPO_ROOT, stdout=log, stderr=log,
                           start_new_session=True)
    try:
        _wait(lambda: (out / "signals.f64").exists() and len(_spooled_rows(out)) >= 100,
              "100 spooled rows")
        refused = _cosim("recover", str(out))
        assert refused.returncode == 2, refused.stderr
        line = refused.stderr.strip()
        match = re.fullmatch(rf"error: run folder {re.escape(str(out))} is still being written by a "
                             rf"running run \(pid (\d+)\); recover it after it ends", line)
        assert match, line
        master = int(match.group(1))
        assert (out / "signals.f64").exists() and run.poll() is None
        rows = len(_spooled_rows(out))
        time.sleep(0.3)
        assert len(_spooled_rows(out)) > rows  # the run goes on
        # the supervisor first (it would complete the folder itself), then the master
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        os.kill(master, signal.SIGKILL)
        _wait(lambda: not os.path.exists(f"/proc/{master}"), "the master to end")
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
        log.close()
    rows = len(_spooled_rows(out))
    done = _cosim("recover", str(out))
    assert done.returncode == 0, done.stderr
    assert f"signals.csv: {rows} rows" in done.stdout
    names, data = read_signals(out / "signals.csv")
    assert names[0] == "time" and data.shape[0] == rows > 100
    assert json.loads((out / "manifest.json").read_text())["status"] == "recovered"
    assert not list(out.rglob("*.f64*"))


def test_the_supervisor_salvage_says_when_the_spools_could_not_be_rebuilt(tmp_path):
    from cosim.results.salvage import complete_run_folder

    (tmp_path / "manifest.json").write_text(json.dumps({"status": "running",
                                                        "scenario": {"tick": 0.01}}))
    (tmp_path / "signals.f64.json").write_text(json.dumps(
        {"format": "cosim-spool-f64", "csv": "signals.csv", "columns": ["time", "a"],
         "byteorder": "sideways"}))
    message = complete_run_folder(tmp_path, {"kind": "signal", "signal": "SIGKILL", "call": None})
    assert message.endswith("; the CSV files were not rebuilt: "
                            f"{tmp_path / 'signals.f64.json'}: byteorder: expected 'little' or "
                            "'big', got 'sideways' (spools kept for cosim recover)")
    assert json.loads((tmp_path / "manifest.json").read_text())["error"] == message
    assert (tmp_path / "signals.f64.json").exists()
