"""Zenoh's runtime on one thread in a run's processes (cosim.transport.zenoh.runtime):
the master's first session and every component process, a user's ZENOH_RUNTIME kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.transport.zenoh import ZenohComponents, runtime
from cosim.transport.zenoh.processes import _child_env
from tests.helpers.components import launch

ROOT = Path(__file__).resolve().parents[2]
POOLS = ("acc", "tx", "rx", "net")  # the pools Zenoh starts besides app


def thread_kinds(pid: int | str = "self") -> set[str]:
    """The names of a process's threads without their numbers ("app-0" -> "app")."""
    kinds = set()
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/comm") as comm:
            kinds.add(comm.read().strip().rstrip("0123456789").rstrip("-"))
    return kinds


def test_a_child_gets_one_runtime_thread(monkeypatch):
    monkeypatch.delenv(runtime.ENV, raising=False)
    assert _child_env("r1")[runtime.ENV] == runtime.ONE_THREAD


def test_a_child_asked_for_the_pools_gets_no_setting(monkeypatch):
    monkeypatch.delenv(runtime.ENV, raising=False)
    assert runtime.ENV not in _child_env("r1", one_runtime_thread=False)


def test_a_users_runtime_setting_reaches_the_child(monkeypatch):
    monkeypatch.setenv(runtime.ENV, runtime.DEFAULT_POOLS)
    assert _child_env("r1")[runtime.ENV] == runtime.DEFAULT_POOLS


@pytest.fixture
def fresh_process(monkeypatch):
    """This process as if no session had opened yet, with no ZENOH_RUNTIME of its own."""
    monkeypatch.setattr(runtime, "_chosen", False)
    monkeypatch.setattr(runtime, "_one_thread_chosen", False)
    monkeypatch.delenv(runtime.ENV, raising=False)


def test_the_first_session_sees_one_thread_and_the_environment_is_restored(fresh_process):
    with runtime.first_session():
        assert os.environ[runtime.ENV] == runtime.ONE_THREAD
    assert runtime.ENV not in os.environ


def test_later_sessions_leave_the_environment_alone(fresh_process):
    with runtime.first_session():
        pass
    with runtime.first_session():  # the runtime is chosen: nothing to set, nothing to race
        assert runtime.ENV not in os.environ


def test_a_first_session_asked_for_the_pools_sets_nothing_and_chooses(fresh_process):
    with runtime.first_session(one_thread=False):
        assert runtime.ENV not in os.environ
    assert runtime._chosen
    with runtime.first_session():  # the process's runtime is chosen: the pools
        assert runtime.ENV not in os.environ


def test_asking_for_the_pools_after_one_thread_was_chosen_is_warned(fresh_process):
    with runtime.first_session():
        pass
    with pytest.warns(RuntimeWarning, match="fresh process"), runtime.first_session(one_thread=False):
        assert runtime.ENV not in os.environ


def test_a_users_setting_is_kept_for_the_first_session(fresh_process, monkeypatch):
    monkeypatch.setenv(runtime.ENV, "(app: (worker_threads: 2))")
    with runtime.first_session():
        assert os.environ[runtime.ENV] == "(app: (worker_threads: 2))"
    assert os.environ[runtime.ENV] == "(app: (worker_threads: 2))"


def test_an_interrupted_first_session_restores_the_environment(fresh_process):
    with pytest.raises(KeyboardInterrupt), runtime.first_session():
        raise KeyboardInterrupt
    assert runtime.ENV not in os.environ
    with runtime.first_session():  # and counts as the first
        assert runtime.ENV not in os.environ


@pytest.mark.integration
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs /proc")
def test_component_processes_run_zenoh_on_one_thread(monkeypatch):
    monkeypatch.delenv(runtime.ENV, raising=False)  # a user's setting would be theirs
    with ZenohComponents([launch("echo", "Echo")], run_id=f"t-rt-{os.getpid()}") as hosted:
        echo = hosted.components["echo"]
        echo.start(0.0, {"u": 1.0})
        assert set(echo.step(1, 0.01, {"u": 2.0})) == {"y"}  # it answers over the runtime
        kinds = thread_kinds(hosted.pids["echo"])
        echo.stop()
    assert "app" in kinds and not kinds & set(POOLS), kinds


MASTER = """
import json, os, sys
sys.path.insert(0, sys.argv[1])
from cosim.transport.zenoh import ZenohComponents
from tests.helpers.components import launch
from tests.transport.test_zenoh_runtime import thread_kinds
ZenohComponents.one_runtime_thread = sys.argv[2] == "one"
with ZenohComponents([launch("echo", "Echo")], run_id="t-rt-master-%d" % os.getpid()) as hosted:
    echo = hosted.components["echo"]
    echo.start(0.0, {"u": 1.0})
    echo.step(1, 0.01, {"u": 2.0})
    print(json.dumps({"master": sorted(thread_kinds()), "env": os.environ.get("ZENOH_RUNTIME"),
                      "child": sorted(thread_kinds(hosted.pids["echo"]))}))
    echo.stop()
"""


@pytest.mark.integration
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs /proc")
@pytest.mark.parametrize("setting, asked, pools_expected", [
    (None, "one", False), (runtime.DEFAULT_POOLS, "one", True), (None, "pools", True)])
def test_a_fresh_master_process_opens_its_session_on_one_thread_unless_told(
        setting, asked, pools_expected):
    """A user's setting wins; a host asking for the pools (runs with workers) gets them."""
    env = {k: v for k, v in os.environ.items() if k != runtime.ENV}
    if setting is not None:
        env[runtime.ENV] = setting
    done = subprocess.run([sys.executable, "-c", MASTER, str(ROOT), asked], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["env"] == setting  # the master's environment is as it was
    for process in ("master", "child"):
        pools = set(seen[process]) & set(POOLS)
        assert bool(pools) == pools_expected, (process, seen)

