"""`cosim run` leaves no process behind, whatever the master forgot: the supervisor
ends the master's process group and the orphans it adopted as its subreaper, and
reaps those that end during the run.

The stand-in for a lost handle (a Ctrl-C between a component process's fork and
the master's record of it) is a component that starts processes and drops them:
one in the master's process group, one in a session of its own, and a chain of
shells in a session of its own, each adopted only once the one above it has ended.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.results.recorder import read_signals
from cosim.transport.zenoh.processes import process_state
from tests.helpers.paths import REPO_ROOT

COSIM = Path(sys.executable).with_name("cosim")
DROPPER = '''
import os, subprocess, time
from cosim.component import Component, Port

QUIET = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
# N shells, each waiting for the next (`; :` keeps it from exec'ing), then a sleep whose
# pid goes to FILE: each is adopted only once the one above it has ended
CHAIN = ('if [ "$1" -gt 0 ]; then sh -c "$0" "$0" $(($1 - 1)) "$2"; :; '
         'else echo $$ > "$2"; exec sleep 300; fi')  # $0: this script


class Dropper(Component):
    """Starts processes it never ends, writes their pids to `pid_file`."""

    inputs = ()
    outputs = (Port("y"),)

    def __init__(self, pid_file: str) -> None:
        kept = subprocess.Popen(["sleep", "300"], **QUIET)
        own_session = subprocess.Popen(["sleep", "300"], start_new_session=True, **QUIET)
        inner_file = pid_file + ".inner"
        subprocess.Popen(["sh", "-c", CHAIN, CHAIN, "3", inner_file], start_new_session=True,
                         **QUIET)
        while not os.path.exists(inner_file) or not open(inner_file).read().strip():
            time.sleep(0.005)
        with open(pid_file, "w") as f:
            f.write(f"{kept.pid} {own_session.pid} {open(inner_file).read().strip()}")

    def step(self, t, inputs):
        return {"y": t}


class Orphans(Component):
    """Each step, a process that ends at once and whose parent does not wait for it
    (`sh -c 'true &'`); its output counts the zombie children of the master's parent."""

    inputs = ()
    outputs = (Port("zombies"),)

    def step(self, t, inputs):
        subprocess.run(["sh", "-c", "true &"], **QUIET)
        time.sleep(0.002)
        return {"zombies": float(_zombie_children(os.getppid()))}


def _zombie_children(pid):
    try:
        children = open(f"/proc/{pid}/task/{pid}/children").read().split()
    except OSError:
        return -1.0
    count = 0
    for child in children:
        try:
            count += open(f"/proc/{child}/stat").read().rpartition(")")[2].split()[0] == "Z"
        except OSError:
            pass
    return count
'''
SCENARIO = """\
name: dropper
duration: {duration}
tick: 0.01
components:
  {name}:
    python: dropper:{cls}
    parameters: {parameters}
"""


def _running(pid: int) -> bool:
    """Whether `pid` exists and is not a zombie."""
    return process_state(pid) not in ("", "Z", "X")


def _run(tmp_path: Path, transport: str, **scenario: str) -> subprocess.CompletedProcess:
    (tmp_path / "dropper.py").write_text(DROPPER)
    (tmp_path / "s.yaml").write_text(SCENARIO.format(**scenario))
    proc = subprocess.Popen([str(COSIM), "run", str(tmp_path / "s.yaml"), "--out",
                             str(tmp_path / "run"), "--no-figures", "--transport", transport],
                            cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # end the whole session: the master has a group of its own
        for pid in subprocess.run(["pgrep", "-s", str(proc.pid)], capture_output=True,
                                  text=True).stdout.split():
            os.kill(int(pid), 9)
        raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_processes_a_run_left_running_are_ended_before_cosim_run_exits(tmp_path, transport):
    pid_file = tmp_path / "pids"
    done = _run(tmp_path, transport, duration=0.05, name="dropper", cls="Dropper",
                parameters=f"{{pid_file: {pid_file}}}")
    assert done.returncode == 0, done.stderr
    pids = [int(p) for p in pid_file.read_text().split()]
    assert len(pids) == 3
    try:
        # checked at once: cosim run has exited, nothing may still be on its way out
        assert [p for p in pids if _running(p)] == []
    finally:
        for pid in pids:
            if _running(pid):
                os.kill(pid, 9)


def test_orphans_that_end_during_the_run_are_reaped_as_they_end(tmp_path):
    done = _run(tmp_path, "inproc", duration=0.5, name="orphans", cls="Orphans", parameters="{}")
    assert done.returncode == 0, done.stderr
    names, rows = read_signals(tmp_path / "run" / "signals.csv")
    zombies = rows[:, names.index("orphans.zombies")]
    assert len(zombies) == 51
    # 50 orphans adopted by the supervisor: without reaping they pile up (40 and more by then)
    assert zombies.min() >= 0 and zombies[-10:].min() <= 2, zombies.tolist()
