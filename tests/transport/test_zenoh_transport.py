"""Lockstep over Zenoh with real component processes, checked bit for bit
against the same components hosted in-process."""

from __future__ import annotations

import os

import numpy as np
import pytest

from cosim.transport.inproc import InprocComponent
from cosim.transport.zenoh import ZenohComponents
from cosim.transport.zenoh.auth import new_credential
from tests.helpers.components import bits, launch, run_processes

pytestmark = pytest.mark.integration
TICK = 0.01


def drive(remote, local, rng, ticks: int, gain_u: float = 1.0) -> int:
    """Step a remote and an in-process copy with the same random inputs; assert
    identical outputs at every tick; return the number of ticks compared."""
    def inputs():
        return {"u": gain_u * rng.standard_normal() * 10.0 ** rng.integers(-3, 3),
                "w": rng.standard_normal(3)}
    first = inputs()
    assert bits(remote.start(0.0, first)) == bits(local.start(0.0, first))
    for k in range(1, ticks + 1):
        values = inputs()
        assert bits(remote.step(k, k * TICK, values)) == bits(local.step(k, k * TICK, values)), k
    return ticks


def test_three_processes_match_inproc_bit_for_bit():
    specs = [launch("mix_a", "Mixer", gain=1.5), launch("mix_b", "Mixer", 2, gain=-0.25),
             launch("echo", "Echo")]
    local = {s.name: InprocComponent(s) for s in specs}
    run_id = f"t-bits-{os.getpid()}"
    with ZenohComponents(specs, run_id=run_id) as hosted:
        remote = hosted.components
        assert list(remote) == ["mix_a", "mix_b", "echo"]  # declaration order
        for name, comp in remote.items():  # the handshake carried the declarations
            assert comp.inputs == local[name].inputs and comp.outputs == local[name].outputs
            assert comp.period_ticks == local[name].period_ticks
            with open(f"/proc/{hosted.pids[name]}/cmdline", "rb") as f:
                argv = f.read().split(b"\0")
            assert argv[argv.index(b"--name") + 1] == name.encode()  # ps tells which is which
        rng = np.random.default_rng(5)
        drive(remote["mix_a"], local["mix_a"], rng, 300)
        drive(remote["mix_b"], local["mix_b"], rng, 50)
        echo_in = {"u": 0.1}
        assert bits(remote["echo"].start(0.0, echo_in)) == bits(local["echo"].start(0.0, echo_in))
        for k in range(1, 20):
            echo_in = {"u": echo_in["u"] * 1.1}
            assert bits(remote["echo"].step(k, k * TICK, echo_in)) \
                == bits(local["echo"].step(k, k * TICK, echo_in))
        for name in ["mix_a", "mix_b", "echo"]:
            assert remote[name].stop() == local[name].stop()
    assert run_processes(run_id) == []


def test_two_runs_on_one_network_do_not_mix():
    """Two masters joined peer to peer, same component names, different run ids (one
    credential for both, as with a shared one: otherwise they could not even link)."""
    spec_a, spec_b = launch("mixer", "Mixer", gain=2.0), launch("mixer", "Mixer", gain=-3.0)
    local_a, local_b = InprocComponent(spec_a), InprocComponent(spec_b)
    shared = new_credential("shared")
    with ZenohComponents([spec_a], run_id=f"t-a-{os.getpid()}", credential=shared) as run_a, \
            ZenohComponents([spec_b], run_id=f"t-b-{os.getpid()}", connect=[run_a.endpoint],
                            credential=shared) as run_b:
        remote_a, remote_b = run_a.components["mixer"], run_b.components["mixer"]
        rng = np.random.default_rng(9)
        inputs = {"u": 1.25, "w": np.array([0.5, -0.25, 2.0])}
        assert bits(remote_a.start(0.0, inputs)) == bits(local_a.start(0.0, inputs))
        assert bits(remote_b.start(0.0, inputs)) == bits(local_b.start(0.0, inputs))
        for k in range(1, 101):  # interleaved, different inputs per run
            in_a = {"u": rng.standard_normal(), "w": rng.standard_normal(3)}
            in_b = {"u": rng.standard_normal(), "w": rng.standard_normal(3)}
            assert bits(remote_a.step(k, k * TICK, in_a)) == bits(local_a.step(k, k * TICK, in_a))
            assert bits(remote_b.step(k, k * TICK, in_b)) == bits(local_b.step(k, k * TICK, in_b))
        assert remote_a.stop() == local_a.stop()
        assert remote_b.stop() == local_b.stop()


def test_exit_on_exception_leaves_no_process():
    run_id = f"t-exc-{os.getpid()}"
    with pytest.raises(KeyboardInterrupt):
        with ZenohComponents([launch("echo", "Echo"), launch("mixer", "Mixer")], run_id) as hosted:
            assert sorted(run_processes(run_id)) == sorted(hosted.pids.values())
            hosted.components["echo"].start(0.0, {"u": 1.0})
            raise KeyboardInterrupt
    assert run_processes(run_id) == []


def test_master_killed_its_processes_exit_by_themselves(tmp_path):
    """A master that dies without cleaning up: its components see its liveliness
    token vanish and exit on their own."""
    import signal
    import subprocess
    import sys
    import time
    run_id = f"t-orphan-{os.getpid()}"
    script = ("import os, signal\n"
              "from cosim.transport.zenoh import ZenohComponents\n"
              "from tests.helpers.components import launch\n"
              f"z = ZenohComponents([launch('echo', 'Echo')], {run_id!r}).__enter__()\n"
              "print('up', flush=True)\n"
              "os.kill(os.getpid(), signal.SIGKILL)\n")
    master = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            cwd=os.getcwd(), env={**os.environ, "PYTHONPATH": os.getcwd()},
                            timeout=60)
    assert master.stdout == "up\n" and master.returncode == -signal.SIGKILL
    end = time.monotonic() + 20
    while run_processes(run_id) and time.monotonic() < end:
        time.sleep(0.05)
    assert run_processes(run_id) == []


def test_spawn_early_then_wait_ready():
    """Start-up in two steps, so the master can load FMUs while the processes start."""
    run_id = f"t-spawn-{os.getpid()}"
    hosted = ZenohComponents([launch("echo", "Echo")], run_id)
    try:
        hosted.spawn()
        assert list(hosted.pids) == ["echo"]
        with pytest.raises(RuntimeError, match="before the handshake"):
            hosted.components
        ready = hosted.wait_ready()
        assert ready is hosted.components and hosted.wait_ready() is ready
        assert ready["echo"].start(0.0, {"u": 2.5}) == {"y": 3.5}
    finally:
        hosted.close()
    assert run_processes(run_id) == []


def test_slow_constructor_then_normal_exchanges():
    """A component that takes longer to build than many handshake retries."""
    with ZenohComponents([launch("slow", "SlowStart", seconds=1.5)], f"t-slow-{os.getpid()}",
                         deadline_s=2.0) as hosted:
        slow = hosted.components["slow"]
        assert slow.start(0.0, {"u": 1.0}) == {"y": 2.0}
        assert [slow.step(k, k * TICK, {"u": float(k)})["y"] for k in range(1, 6)] \
            == [2.0, 4.0, 6.0, 8.0, 10.0]
