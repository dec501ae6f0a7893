"""COSIM_JIT=auto leaves numba out of a controller built for a short run (controllers.jit.
for_this_component): interpreted below SHORT_RUN_STEPS, compiled from there on, when the
steps are unknown, when the compiled parts are loaded in the process already, and with on."""

from __future__ import annotations

import pytest

from controllers import jit
from controllers.backstepping import step_kernel, step_path
from controllers.backstepping.component import BacksteppingController
from controllers.road import projection
from cosim.component import constructing_for

pytest.importorskip("numba")



def paths(steps: int | None) -> tuple[bool, bool]:
    """(projection compiled, step compiled) of a controller built for `steps`."""
    with constructing_for(steps):
        controller = BacksteppingController()
    return controller.reader._compiled, controller._step is not step_kernel.step


def test_auto_builds_a_short_run_interpreted_and_loads_nothing(fresh):
    fresh("auto")
    assert paths(jit.SHORT_RUN_STEPS - 1) == (False, False)
    assert not jit.is_loaded(projection.compiled_kernel)  # numba not even asked
    assert not jit.is_loaded(step_path.compiled_step)


@pytest.mark.parametrize("steps", [jit.SHORT_RUN_STEPS, None], ids=["long", "unknown"])
def test_auto_compiles_a_long_run_or_one_of_unknown_length(fresh, steps):
    fresh("auto")
    assert paths(steps) == (True, True)


def test_once_loaded_a_short_run_is_compiled_too(fresh):
    fresh("auto")
    assert paths(None) == (True, True)
    assert paths(10) == (True, True)  # the cost is paid: nothing left to save


def test_on_compiles_a_short_run_and_off_a_long_one_not(fresh):
    fresh("on")
    assert paths(10) == (True, True)
    fresh("off")
    assert paths(jit.SHORT_RUN_STEPS * 10) == (False, False)
