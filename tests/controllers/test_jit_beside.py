"""Compiled parts loaded beside the run (controllers.jit.beside_the_run): in a component process
under COSIM_JIT=auto, a controller steps interpreted while its compiled projection and step load on
a thread of their own, then takes them between two steps, with the same bits as the interpreted
controller throughout."""

from __future__ import annotations

import gc
import sys
import threading
import time
import warnings

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


def _wait_until_ready(*laters) -> None:
    deadline = time.monotonic() + LOAD_TIMEOUT_S
    while not all(later.ready for later in laters):
        assert time.monotonic() < deadline, "the load beside the run did not end"
        time.sleep(0.005)


class _Gate:
    """A load beside the run (ended already) that the test lets through at a step of its choosing,
    its kernel seen through `wrap`."""

    def __init__(self, later: jit.Later, wrap=lambda kernel: kernel) -> None:
        self.later, self.open, self.wrap = later, False, wrap

    @property
    def ready(self) -> bool:
        return self.open and self.later.ready

    @property
    def kernel(self):
        return self.wrap(self.later.kernel)


class _CountingStepOnFeet:
    """A compiled step whose step on the projection's buffer notes the step it is called in."""

    def __init__(self, kernel, stepping: "_Stepping") -> None:
        self.kernel, self.stepping = kernel, stepping

    def __getattr__(self, name: str):
        return getattr(self.kernel, name)

    def step_on_feet(self, *arguments):
        self.stepping.on_feet.append(self.stepping.steps)
        return self.kernel.step_on_feet(*arguments)


class _Stepping:
    """The controller in the closed loop, its projection let through before step `projection_at` and
    its step before step `step_at`; notes which paths each step took."""

    def __init__(self, controller: BacksteppingController, projection_at: int, step_at: int) -> None:
        self.controller, self.steps = controller, 0
        controller.reader._later = _Gate(controller.reader._later)
        controller._later = _Gate(controller._later, lambda kernel: _CountingStepOnFeet(kernel, self))
        self.opening = {projection_at: [controller.reader._later], step_at: [controller._later]}
        if projection_at == step_at:
            self.opening[step_at] = [controller.reader._later, controller._later]
        self.step_compiled: list[bool] = []      # per step: the compiled step was in use after it
        self.window_compiled: list[bool] = []    # per step: its window was prepared compiled
        self.on_feet: list[int] = []             # the steps made on the compiled projection's buffer

    def initialize(self, t, inputs):
        return self.controller.initialize(t, inputs)

    def step(self, t, inputs):
        self.steps += 1
        for gate in self.opening.get(self.steps, ()):
            gate.open = True
        outputs = self.controller.step(t, inputs)
        controller = self.controller
        self.step_compiled.append(controller._step is not step_kernel.step)
        self.window_compiled.append(controller.reader._prepared.compiled_feet is not None)
        return outputs


def _closed_loop(controller) -> dict[str, bytes]:
    plant = LinearPlant(VehicleParams(), substeps=2, vx0=9.0, y0=0.4, mu=0.9)
    record = run_closed_loop(controller, plant, CirclePath(40.0), 5.0)
    return {name: values.tobytes() for name, values in record.items()}


SETTINGS = dict(lateral_law="feedforward", adaptive=True, adaptation="robust", mu0=0.6)


def _loading_beside() -> BacksteppingController:
    with constructing_for(jit.SHORT_RUN_STEPS, load_beside=True):
        controller = BacksteppingController(**SETTINGS)
    assert controller._later is not None and controller.reader._later is not None
    assert controller._step is step_kernel.step and not controller.reader._compiled   # nothing waited for
    return controller


@pytest.fixture
def interpreted(fresh) -> dict[str, bytes]:
    """The closed loop of the interpreted controller; COSIM_JIT=auto, nothing loaded, afterwards."""
    fresh("off")
    record = _closed_loop(BacksteppingController(**SETTINGS))
    fresh("auto")
    return record


def test_a_controller_loading_beside_steps_on_while_it_loads_with_the_same_bits(interpreted):
    controller = _loading_beside()
    laters = (controller.reader._later, controller._later)
    assert _closed_loop(controller) == interpreted         # the loads end whenever they end
    _wait_until_ready(*laters)
    assert gc.isenabled()   # collection was held back while they loaded, and given back


# (the step the projection is let through at, the step the backstepping step is): either first,
# both at a window's first step (every 10th) or within a window, a long stretch with one only
@pytest.mark.parametrize("projection_at, step_at", [(40, 45), (45, 40), (41, 80), (80, 41), (40, 40), (47, 47)])
def test_taking_the_compiled_parts_between_two_steps_keeps_every_bit(interpreted, projection_at, step_at):
    controller = _loading_beside()
    _wait_until_ready(controller.reader._later, controller._later)
    stepping = _Stepping(controller, projection_at, step_at)
    assert _closed_loop(stepping) == interpreted

    assert controller._later is None and controller.reader._later is None   # both taken
    steps = range(1, len(stepping.step_compiled) + 1)
    assert stepping.step_compiled == [k >= step_at for k in steps]
    # the projection from the read that takes it, the window of that step prepared again
    assert stepping.window_compiled == [k >= projection_at for k in steps]
    assert stepping.on_feet == [k for k in steps if k >= max(projection_at, step_at)]


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


def _broken_gate():
    raise RuntimeError("no LLVM today")


_broken_gate.cache_info = lambda: type("Info", (), {"currsize": 0})()   # jit.is_loaded asks it


class _WarningsAsErrors(warnings.catch_warnings):
    """warnings.catch_warnings with every warning an error inside."""

    def __enter__(self):
        entered = super().__enter__()
        warnings.simplefilter("error")
        return entered


# the warning is seen; under warnings-as-errors (-W error) the load ends all the same
@pytest.mark.parametrize("filters", [
    lambda: pytest.warns(RuntimeWarning, match="a compiled part is not used: RuntimeError"),
    _WarningsAsErrors,
], ids=["warning", "warnings-as-errors"])
def test_a_load_that_fails_leaves_the_interpreted_path(fresh, filters):
    fresh("auto")
    with filters():
        with constructing_for(None, load_beside=True):
            later = jit.beside_the_run(_broken_gate)
        _wait_until_ready(later)
    assert later.kernel is None


def test_the_reader_takes_the_compiled_projection_without_a_new_window(fresh):
    fresh("auto")
    controllers = []
    for _ in range(2):   # one lets its loads through at step 3, its twin never
        fresh("auto")    # each loads beside the run
        with constructing_for(None, load_beside=True):
            controller = BacksteppingController()
        _wait_until_ready(controller._later, controller.reader._later)
        controller.reader._later, controller._later = _Gate(controller.reader._later), _Gate(controller._later)
        controllers.append(controller)
    taking, twin = controllers
    s = np.arange(64.0)
    window = tuple(np.array(field) for field in
                   (s, 0.01 * s, np.zeros(64), np.zeros(64), s, np.full(64, 10.0), np.zeros(64)))
    for k in range(1, 6):       # the same window's arrays at every step
        if k == 3:
            taking.reader._later.open = taking._later.open = True
        plant = (3.0 + 0.1 * k, 0.2, 0.01, 10.0, 0.0, 0.001)
        assert repr(taking.step_values(0.01 * k, plant + window)) == repr(twin.step_values(0.01 * k, plant + window))
    assert taking.reader._later is None and taking.reader._prepared.compiled_feet is not None
    assert twin.reader._prepared.compiled_feet is None and taking._step is not step_kernel.step


def test_without_a_thread_to_be_had_the_part_loads_at_once_and_nothing_stays_held(fresh, monkeypatch):
    fresh("auto")

    def refused(self):
        raise RuntimeError("can't start new thread")
    monkeypatch.setattr(threading.Thread, "start", refused)
    with constructing_for(None, load_beside=True):
        controller = BacksteppingController()
    monkeypatch.undo()
    assert controller._later is None and controller.reader._later is None      # loaded before it returned
    assert controller.reader._compiled and controller._step is not step_kernel.step
    assert gc.isenabled() and not jit._loading and not jit._waiting


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
