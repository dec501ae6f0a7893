"""`cosim run` leaves no process behind, whatever the master forgot: the supervisor
ends the master's process group and the orphans it adopted as its subreaper.

The stand-in for a lost handle (a Ctrl-C between a component process's fork and
the master's record of it) is a component that starts two `sleep`s and drops
them: one in the master's process group, one in a session of its own.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.paths import REPO_ROOT

COSIM = Path(sys.executable).with_name("cosim")
DROPPER = '''
import os, subprocess
from cosim.component import Component, Port


class Dropper(Component):
    """Starts two processes it never ends, writes their pids to `pid_file`."""

    inputs = ()
    outputs = (Port("y"),)

    def __init__(self, pid_file: str) -> None:
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
        kept = subprocess.Popen(["sleep", "300"], **quiet)
        own_session = subprocess.Popen(["sleep", "300"], start_new_session=True, **quiet)
        with open(pid_file, "w") as f:
            f.write(f"{kept.pid} {own_session.pid}")

    def step(self, t, inputs):
        return {"y": t}
'''
SCENARIO = """\
name: dropper
duration: 0.05
tick: 0.01
components:
  dropper:
    python: dropper:Dropper
    parameters: {{pid_file: {pid_file}}}
"""


def _running(pid: int) -> bool:
    """Whether `pid` exists and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rpartition(")")[2].split()[0] != "Z"


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_processes_a_run_left_running_are_ended_before_cosim_run_exits(tmp_path, transport):
    (tmp_path / "dropper.py").write_text(DROPPER)
    pid_file = tmp_path / "pids"
    scenario = tmp_path / "s.yaml"
    scenario.write_text(SCENARIO.format(pid_file=pid_file))
    done = subprocess.run([str(COSIM), "run", str(scenario), "--out", str(tmp_path / "run"),
                           "--no-figures", "--transport", transport], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=120, start_new_session=True)
    assert done.returncode == 0, done.stderr
    pids = [int(p) for p in pid_file.read_text().split()]
    try:
        # checked at once: cosim run has exited, nothing may still be on its way out
        assert [p for p in pids if _running(p)] == []
    finally:
        for pid in pids:
            if _running(pid):
                os.kill(pid, 9)
