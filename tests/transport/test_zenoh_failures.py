"""Component failures over Zenoh: each one a ComponentFailure (or UserError at
start-up) naming the component, the tick and the cause; no process left."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time

import numpy as np
import pytest

from cosim.errors import ComponentFailure, UserError
from cosim.transport.inproc import InprocComponent
from cosim.transport.zenoh import ZenohComponents
from cosim.transport.zenoh.processes import process_state
from tests.helpers.components import launch, run_processes

pytestmark = [pytest.mark.integration, pytest.mark.timeout(60)]
TICK = 0.01
W = np.array([0.25, 0.5, -1.0])


def fail_at_step(specs, name, ticks, deadline_s=30.0, before_step=None):
    """Run `name` for up to `ticks` ticks; return the ComponentFailure it raised.

    Args:
        before_step: called as before_step(hosted, k) before each step, or None.
    """
    run_id = f"t-fail-{name}-{os.getpid()}"
    with pytest.raises(ComponentFailure) as caught:
        with ZenohComponents(specs, run_id, deadline_s=deadline_s) as hosted:
            comp = hosted.components[name]
            comp.start(0.0, {"u": 1.0, "w": W})
            for k in range(1, ticks + 1):
                if before_step:
                    before_step(hosted, k)
                comp.step(k, k * TICK, {"u": 1.0, "w": W})
    assert run_processes(run_id) == []
    return caught.value


def test_exception_text_comes_back_with_tick_and_time():
    failure = fail_at_step([launch("mixer", "Mixer", fail_at=0.045)], "mixer", 10)
    assert (failure.component, failure.tick, failure.time) == ("mixer", 5, 5 * TICK)
    assert failure.cause == "ZeroDivisionError: mixer cannot divide at t=0.05"
    inproc = InprocComponent(launch("mixer", "Mixer", fail_at=0.045))
    inproc.start(0.0, {"u": 1.0, "w": W})
    with pytest.raises(ComponentFailure) as local:
        for k in range(1, 11):
            inproc.step(k, k * TICK, {"u": 1.0, "w": W})
    assert str(local.value) == str(failure)  # same message in both transports


def test_nan_output_is_named():
    failure = fail_at_step([launch("mixer", "Mixer", nan_at=0.025)], "mixer", 10)
    assert (failure.component, failure.tick) == ("mixer", 3)
    assert failure.cause == "output 'z' is non-finite at [1]: nan"


def test_killed_process_fails_by_death_detection_not_deadline():
    """SIGKILL while the master waits for its reply; with a 30 s deadline only the
    death detection can produce this failure (pytest's timeout is 60 s)."""
    def kill_soon(hosted, k):
        if k == 3:
            threading.Timer(0.3, os.kill, (hosted.pids["sleeper"], signal.SIGKILL)).start()
    specs = [launch("sleeper", "Sleeper", after=0.025), launch("mixer", "Mixer")]
    failure = fail_at_step(specs, "sleeper", 5, deadline_s=30.0, before_step=kill_soon)
    assert (failure.component, failure.tick) == ("sleeper", 3)
    assert failure.cause == "process killed by SIGKILL"


def _wait_until_dead(pid: int) -> None:
    """Until `pid` is a zombie or gone, read from /proc: not reaped here (os.waitid would
    race the host's watchdog, which polls the same child)."""
    end = time.monotonic() + 10
    while time.monotonic() < end:
        if process_state(pid) in ("", "Z", "X"):
            return
        time.sleep(0.001)
    raise AssertionError(f"process {pid} still alive 10 s after SIGKILL")


def test_process_killed_between_ticks_fails_at_next_step():
    def kill_now(hosted, k):
        if k == 4:
            pid = hosted.pids["mixer"]
            os.kill(pid, signal.SIGKILL)
            _wait_until_dead(pid)  # dead before we step
    failure = fail_at_step([launch("mixer", "Mixer")], "mixer", 10, before_step=kill_now)
    assert (failure.component, failure.tick) == ("mixer", 4)
    assert failure.cause == "process killed by SIGKILL"


def test_stopped_process_fails_after_the_deadline():
    def stop_it(hosted, k):
        if k == 2:
            os.kill(hosted.pids["mixer"], signal.SIGSTOP)
    failure = fail_at_step([launch("mixer", "Mixer")], "mixer", 10, deadline_s=0.5,
                           before_step=stop_it)
    assert (failure.component, failure.tick) == ("mixer", 2)
    assert failure.cause == "no reply within the deadline of 0.5 s (process stopped or not responding)"


def test_after_a_failure_the_others_still_stop_cleanly():
    """The master calls stop() on every component after a failure: the failed one
    raises nothing more, the healthy one returns its metrics."""
    run_id = f"t-sticky-{os.getpid()}"
    with ZenohComponents([launch("bad", "Mixer", fail_at=0.015), launch("good", "Mixer")],
                         run_id) as hosted:
        bad, good = hosted.components["bad"], hosted.components["good"]
        for comp in (bad, good):
            comp.start(0.0, {"u": 1.0, "w": W})
        good.step(1, TICK, {"u": 1.0, "w": W})
        with pytest.raises(ComponentFailure) as first:
            bad.step(2, 2 * TICK, {"u": 1.0, "w": W})
        with pytest.raises(ComponentFailure) as again:
            bad.step(3, 3 * TICK, {"u": 1.0, "w": W})
        assert again.value is first.value
        assert bad.stop() == {}
        assert good.stop()["steps"] == 2.0


@pytest.mark.parametrize("spec", [
    launch("bad", "BadParameter", mass=-1.0),
    launch("bad", "NoSuchClass"),
    launch("bad", "Mixer", no_such_parameter=1),
], ids=["rejected-parameter", "missing-class", "unknown-parameter"])
def test_construction_errors_read_as_inproc(spec):
    with pytest.raises(UserError) as local:
        InprocComponent(spec)
    with pytest.raises(UserError) as remote:
        with ZenohComponents([spec, launch("echo", "Echo")], f"t-build-{os.getpid()}"):
            pass
    assert str(remote.value) == str(local.value)
    assert run_processes(f"t-build-{os.getpid()}") == []


def test_process_dying_before_handshake():
    with pytest.raises(ComponentFailure) as caught:
        with ZenohComponents([launch("early", "ExitsInInit", code=3)], f"t-early-{os.getpid()}"):
            pass
    assert (caught.value.component, caught.value.tick) == ("early", None)
    assert caught.value.cause == "process exited with code 3 before its handshake"


def test_bad_inputs_from_the_master_are_named():
    run_id = f"t-input-{os.getpid()}"
    with ZenohComponents([launch("mixer", "Mixer")], run_id) as hosted:
        with pytest.raises(ComponentFailure) as caught:
            hosted.components["mixer"].start(0.0, {"u": 1.0, "w": np.zeros(2)})
    assert caught.value.cause == "input 'w' has shape (2,), expected (3,)"


def test_bad_run_id_and_duplicate_names():
    with pytest.raises(ValueError, match="run_id 'a/b'"):
        ZenohComponents([], "a/b")
    with pytest.raises(UserError, match="unique"):
        ZenohComponents([launch("x", "Echo"), launch("x", "Echo")], "dup")


@pytest.mark.parametrize("bad, cause", [(float("nan"), "output 'energy' is non-finite: nan"),
                                        (float("-inf"), "output 'energy' is non-finite: -inf")])
def test_a_bad_output_of_step_values_is_named_as_in_process(bad, cause):
    from cosim.engine.master import Master

    spec = launch("track", "Tracker", bad=bad, bad_at=0.035)
    failures = []
    for hosts in (lambda: contextlib.nullcontext({"track": InprocComponent(spec)}),
                  lambda: _components(ZenohComponents([spec], f"t-lane-{os.getpid()}"))):
        with hosts() as hosted, pytest.raises(ComponentFailure) as caught:
            master = Master(hosted, [], TICK, 10, 0.0, [])
            assert [p.name for p in master._plans if p.step_values is not None] == ["track"]
            master.run()
        failures.append(caught.value)
    inproc, zenoh = failures
    assert (zenoh.component, zenoh.tick, zenoh.cause) == ("track", 4, cause)
    assert str(zenoh) == str(inproc)


@pytest.mark.parametrize("generator, cause", [
    (False, "step_values returned 2 values for 3 outputs"),
    (True, "step_values returned generator, expected a sequence of 3 floats")])
def test_a_step_values_result_of_the_wrong_shape_is_named_as_in_process(generator, cause):
    from cosim.engine.master import Master

    spec = launch("track", "ShortLane", generator=generator)
    failures = []
    for hosts in (lambda: contextlib.nullcontext({"track": InprocComponent(spec)}),
                  lambda: _components(ZenohComponents([spec], f"t-short-{os.getpid()}"))):
        with hosts() as hosted, pytest.raises(ComponentFailure) as caught:
            Master(hosted, [], TICK, 10, 0.0, []).run()
        failures.append(caught.value)
    inproc, zenoh = failures
    assert (zenoh.component, zenoh.tick, zenoh.cause) == ("track", 1, cause)
    assert str(zenoh) == str(inproc)


@contextlib.contextmanager
def _components(host: ZenohComponents):
    with host:
        yield host.components
