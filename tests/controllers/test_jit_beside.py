"""Compiled parts loaded beside the run (controllers.jit.beside_the_run): in a component process
under COSIM_JIT=auto, a controller steps interpreted while its compiled projection and step load on
a thread of their own, then takes them between two steps, with the same bits as the interpreted
controller throughout."""

from __future__ import annotations

import gc
import sys
import threading
import time

import numpy as np
import pytest

from controllers import jit
from controllers.backstepping import step_kernel, step_path
from controllers.backstepping.component import BacksteppingController
from controllers.linear_plant import LinearPlant
from controllers.road import projection
from controllers.vehicle_params import VehicleParams
from cosim.component import BESIDE_THREAD_PREFIX, constructing_for, may_load_beside, start_beside
from tests.helpers.closed_loop import CirclePath, run_closed_loop

pytest.importorskip("numba")

LOAD_TIMEOUT_S = 120.0   # numba compiling afresh into an empty cache, on a slow machine



def _wait_until_ready(*laters: jit.Later) -> None:
    deadline = time.monotonic() + LOAD_TIMEOUT_S
    while not all(later.ready for later in laters):
        assert time.monotonic() < deadline, "the load beside the run did not end"
        time.sleep(0.005)


class _StepsWhileLoading:
    """The controller, with a wait for its loads before step `wait_at`; notes which path each step took."""

    def __init__(self, controller: BacksteppingController, wait_at: int) -> None:
        self.controller, self.wait_at, self.steps = controller, wait_at, 0
        self.compiled: list[bool] = []   # per step: the compiled step was in use after it
        self.on_feet: list[int] = []     # calls of the compiled step on the projection's buffer
        self.laters = (controller.reader._later, controller._later)

    def initialize(self, t, inputs):
        return self.controller.initialize(t, inputs)

    def step(self, t, inputs):
        self.steps += 1
        if self.steps == self.wait_at:
            _wait_until_ready(*self.laters)
        outputs = self.controller.step(t, inputs)
        self.compiled.append(self.controller._step is not step_kernel.step)
        exact = self.controller._step_on_feet
        if exact is not None and not getattr(exact, "counted", False):
            def counted(*arguments):
                self.on_feet.append(1)
                return exact(*arguments)
            counted.counted = True
            self.controller._step_on_feet = counted
        return outputs


def _closed_loop(controller) -> dict[str, bytes]:
    plant = LinearPlant(VehicleParams(), substeps=2, vx0=9.0, y0=0.4, mu=0.9)
    record = run_closed_loop(controller, plant, CirclePath(40.0), 5.0)
    return {name: values.tobytes() for name, values in record.items()}


def _settings() -> dict:
    return dict(lateral_law="feedforward", adaptive=True, adaptation="robust", mu0=0.6)


def test_a_controller_loading_beside_steps_interpreted_then_compiled_with_the_same_bits(fresh):
    fresh("off")
    interpreted = _closed_loop(BacksteppingController(**_settings()))

    fresh("auto")
    with constructing_for(jit.SHORT_RUN_STEPS, load_beside=True):
        controller = BacksteppingController(**_settings())
    assert controller._later is not None and controller.reader._later is not None
    assert controller._step is step_kernel.step and not controller.reader._compiled   # nothing waited for
    stepping = _StepsWhileLoading(controller, wait_at=40)
    assert _closed_loop(stepping) == interpreted

    assert controller._later is None and controller.reader._later is None   # both taken
    assert controller.reader._compiled and controller._step is not step_kernel.step
    assert stepping.compiled[0] is False and stepping.compiled[-1] is True
    assert stepping.compiled.count(False) >= 1 and stepping.compiled.count(True) >= 400
    assert len(stepping.on_feet) >= 400          # new windows prepared compiled: the step on their buffer
    assert gc.isenabled()   # the loader paused collection while it loaded, and gave it back


@pytest.mark.parametrize("mode, steps, allowed, loads_beside", [
    ("auto", jit.SHORT_RUN_STEPS, True, True),
    ("auto", None, True, True),                         # length unknown: as a long run
    ("auto", jit.SHORT_RUN_STEPS - 1, True, False),     # short: interpreted, nothing loaded
    ("auto", jit.SHORT_RUN_STEPS, False, False),        # the host did not allow it: loaded before tick 0
    ("on", jit.SHORT_RUN_STEPS, True, False),           # on: compiled before tick 0, or an error there
    ("off", jit.SHORT_RUN_STEPS, True, False),
], ids=["long", "unknown", "short", "not-allowed", "on", "off"])
def test_which_constructions_load_beside_the_run(fresh, mode, steps, allowed, loads_beside):
    fresh(mode)
    with constructing_for(steps, load_beside=allowed):
        assert may_load_beside() is allowed
        controller = BacksteppingController()
    assert not may_load_beside()                          # only during the construction
    assert (controller._later is not None) is loads_beside
    assert (controller.reader._later is not None) is loads_beside
    if loads_beside:
        _wait_until_ready(controller._later, controller.reader._later)
        assert controller._later.kernel is not None and controller.reader._later.kernel is not None
    compiled_now = mode == "on" or (mode == "auto" and not loads_beside and steps is not None
                                    and steps >= jit.SHORT_RUN_STEPS)
    assert (controller._step is not step_kernel.step) is compiled_now


def test_a_part_this_process_has_loaded_is_taken_at_once(fresh):
    fresh("auto")
    projection.compiled_kernel()
    step_path.compiled_step()
    with constructing_for(None, load_beside=True):
        controller = BacksteppingController()
    assert controller._later is None and controller.reader._later is None
    assert controller.reader._compiled and controller._step is not step_kernel.step


def test_a_load_that_fails_leaves_the_interpreted_path_with_a_warning(fresh):
    fresh("auto")

    def broken():
        raise RuntimeError("no LLVM today")
    broken.cache_info = lambda: type("Info", (), {"currsize": 0})()
    with pytest.warns(RuntimeWarning, match="a compiled part is not used: RuntimeError"):
        with constructing_for(None, load_beside=True):
            later = jit.beside_the_run(broken)
        _wait_until_ready(later)
    assert later.kernel is None


def test_a_thread_beside_carries_its_name_into_the_os():
    go = threading.Event()
    thread = start_beside(lambda: go.wait(10), "probe")
    try:
        assert thread.name == BESIDE_THREAD_PREFIX + "probe" and thread.daemon
        if sys.platform.startswith("linux"):    # what a host that pins the chain reads, once it returned
            with open(f"/proc/self/task/{thread.native_id}/comm") as comm:
                assert comm.read().strip() == BESIDE_THREAD_PREFIX + "probe"
    finally:
        go.set()
        thread.join(10)


def test_the_compiled_step_is_taken_at_the_next_step_even_before_any_window(fresh):
    fresh("auto")
    with constructing_for(None, load_beside=True):
        controller = BacksteppingController()
    feet = controller._feet
    _wait_until_ready(controller._later, controller.reader._later)
    controller.step_values(0.01, (0.0,) * 6 + (np.zeros(2),) * 7)   # an all-zero window: the held outputs
    assert controller._later is None and controller._feet is feet
