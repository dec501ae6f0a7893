"""The backstepping step compiled by numba against the interpreted one: every output, type and bit.

controllers.backstepping.step_kernel runs interpreted or compiled
(controllers.backstepping.step_jit) from one source; the gate
(controllers.backstepping.step_path, through controllers.jit) checks them
at first use and falls back to the interpreted step when they disagree.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from controllers.backstepping import step_kernel, step_path
from controllers.backstepping.component import BacksteppingController
from controllers.linear_plant import LinearPlant
from controllers.road.projection import FEET_SIZE, finish
from controllers.vehicle_params import VehicleParams
from cosim.component import ComponentError
from tests.helpers.jit_gates import assert_refused_after_one_recompile, one_bit_off
from tests.helpers.closed_loop import CirclePath, make_window, run_closed_loop

pytest.importorskip("numba")

VARIANTS = [
    {"lateral_law": "faithful"},
    {"lateral_law": "feedforward", "ff_target": "cg", "adaptive": True},
    {"lateral_law": "feedforward", "ff_target": "preview"},
    {"lateral_law": "faithful", "adaptive": True, "adaptation": "robust", "fwy_max": 50.0},
    {"lateral_law": "feedforward", "adaptive": True, "adaptation": "robust", "a_excite": 0.1},
]


def _feet(rng: np.random.Generator) -> tuple[tuple, tuple]:
    """Random foot() tuples of the CG and the preview point; the preview one beyond an end now and then."""
    def foot(extrapolated: int) -> tuple:
        return (float(rng.uniform(0, 80)), float(rng.uniform(-60, 60)), float(rng.uniform(-60, 60)),
                float(rng.normal(0, 0.8)), float(rng.uniform(-7, 7)), float(rng.normal(0, 0.03)),
                float(rng.normal(0, 0.005)), float(rng.uniform(0, 25)), float(rng.normal(0, 1.5)), extrapolated)
    return foot(int(rng.choice([-1, 0, 0, 0, 0, 0, 0, 1]))), foot(int(rng.choice([-1, 0, 0, 0, 1])))


def _compiled_controller(settings: dict, jit_mode) -> tuple:
    """(controller with `settings` under COSIM_JIT=on, the compiled step module, the interpreted step's constants)."""
    jit_mode("on")
    controller = BacksteppingController(**settings)
    constants = controller.lateral.constants + tuple(controller._constants[step_kernel.LATERAL_SIZE:].tolist())
    return controller, step_path.compiled_step(), constants


@pytest.mark.parametrize("settings", VARIANTS, ids=lambda s: "-".join(str(v) for v in s.values()))
def test_compiled_step_equals_the_interpreted_one_bit_for_bit(settings, jit_mode):
    controller, compiled, constants = _compiled_controller(settings, jit_mode)
    assert controller._step is compiled.step
    rng = np.random.default_rng(17)
    reached = {"rate limited": 0, "angle limited": 0, "torque clipped": 0, "kept": 0, "below v_min": 0}
    for _ in range(3000):
        last = float(rng.uniform(-0.55, 0.55))
        dt = float(rng.uniform(0.001, 0.05) if rng.uniform() < 0.5 else rng.uniform(0.5, 2.0))
        arguments = (dt, float(rng.uniform(0.05, 1.3)), float(rng.normal(0, 1)),
                     last, float(rng.uniform(-7, 7)), float(rng.uniform(0, 30)), float(rng.normal(0, 1)),
                     float(rng.normal(0, 0.4)), *_feet(rng))
        expected = step_kernel.step(constants, *arguments)
        got = compiled.step(controller._constants, *arguments)
        assert repr(got) == repr(expected), arguments
        delta, torque, command, kept = expected[0], expected[1], expected[16], expected[18]
        reached["rate limited"] += abs(delta - last) == pytest.approx(controller.limits.max_delta_rate * arguments[0])
        reached["angle limited"] += abs(delta) == controller.limits.max_delta
        reached["torque clipped"] += torque in (controller.limits.max_torque, controller.limits.min_torque)
        reached["kept"] += kept == 1.0 and delta == command
        reached["below v_min"] += arguments[5] < controller.gains.v_min
    assert all(count > 30 for count in reached.values()), reached


def _unfinished(rng: np.random.Generator, foot: tuple) -> tuple:
    """Foot fields as the projection leaves them for finish: the offset 0.0 unless beyond an end, a
    tangent now and then shorter than finish's 1e-300 floor."""
    tangent = (rng.normal(0, 1e-305), 0.0) if rng.uniform() < 0.02 else tuple(rng.normal(0, 3, 2).tolist())
    return foot[:3] + (foot[3] if foot[9] else 0.0,) + foot[4:10] + tangent


@pytest.mark.parametrize("settings", VARIANTS, ids=lambda s: "-".join(str(v) for v in s.values()))
def test_the_step_on_the_projections_buffer_equals_the_interpreted_step_on_its_feet(settings, jit_mode):
    controller, compiled, constants = _compiled_controller(settings, jit_mode)
    assert controller._step_on_feet is compiled.step_on_feet
    rng, feet = np.random.default_rng(29), np.full(FEET_SIZE, np.nan)
    floored = beyond = cg_beyond = 0
    for _ in range(2000):
        at_cg, preview = (_unfinished(rng, foot) for foot in _feet(rng))
        x, y, preview_x, preview_y = rng.uniform(-60, 60, 4).tolist()
        feet[:12], feet[12:24], feet[24:] = at_cg, preview, (preview_x, preview_y)
        plant = (float(rng.uniform(-7, 7)), float(rng.uniform(0, 30)), float(rng.normal(0, 1)),
                 float(rng.normal(0, 0.4)))
        state = (0.01, float(rng.uniform(0.05, 1.3)), float(rng.normal(0, 1)), float(rng.uniform(-0.55, 0.55)))
        expected = step_kernel.step(constants, *state, *plant, finish(at_cg, x, y),
                                    finish(preview, preview_x, preview_y))
        got = compiled.step_on_feet(controller._constants, feet, math.hypot(*at_cg[10:]),
                                    math.hypot(*preview[10:]), x, y, *state, *plant)
        assert repr(got) == repr(expected), (at_cg, preview, x, y, state, plant)
        floored += math.hypot(*at_cg[10:]) < 1e-300
        beyond += preview[9] != 0
        cg_beyond += at_cg[9] != 0
    assert floored > 10 and beyond > 300 and cg_beyond > 100


def test_the_controller_steps_on_the_projections_buffer_when_both_are_compiled(jit_mode):
    def run(calls: list) -> dict[str, bytes]:
        controller = BacksteppingController(lateral_law="feedforward", adaptive=True, mu0=0.6)
        if controller._step_on_feet is not None:
            exact = controller._step_on_feet
            controller._step_on_feet = lambda *arguments: calls.append(1) or exact(*arguments)
        plant = LinearPlant(VehicleParams(), substeps=2, vx0=9.0, y0=0.4, mu=0.9)
        record = run_closed_loop(controller, plant, CirclePath(40.0), 5.0)
        return {name: values.tobytes() for name, values in record.items()}

    jit_mode("off")
    interpreted_calls, compiled_calls = [], []
    interpreted = run(interpreted_calls)
    jit_mode("on")
    assert run(compiled_calls) == interpreted
    assert interpreted_calls == [] and len(compiled_calls) == 501      # every step, tick 0 (initialize) too


@pytest.mark.parametrize("settings", VARIANTS[3:], ids=["faithful-robust", "feedforward-robust"])
def test_closed_loop_with_the_robust_law_is_the_same_on_both_paths(settings, jit_mode):
    def run() -> dict[str, bytes]:
        plant = LinearPlant(VehicleParams(), substeps=2, vx0=11.0, y0=-0.3, mu=0.9)
        record = run_closed_loop(BacksteppingController(mu0=0.5, **settings), plant, CirclePath(35.0), 12.0,
                                 v_ref=12.0)
        return {name: values.tobytes() for name, values in record.items()}

    jit_mode("off")
    interpreted = run()
    jit_mode("on")
    compiled = run()
    assert compiled == interpreted
    assert len(set(np.frombuffer(interpreted["mu_hat"]))) > 10       # the estimate moved: the rate path ran


@pytest.mark.parametrize("mode", ["off", "on"])
def test_a_singular_feedforward_model_names_the_speed_on_both_paths(mode, jit_mode):
    jit_mode(mode)
    controller = BacksteppingController(Cr=1e-9, lateral_law="feedforward")
    assert (controller._step is step_kernel.step) == (mode == "off")
    path = CirclePath(40.0)
    state = {"x": 40.0, "y": 0.0, "psi": 1.5707963267948966, "vx": 8.0, "vy": 0.0, "r": 0.2}
    signals = make_window(path, path.sigma_of(40.0, 0.0) - 5.0, v=8.0).to_signals("ref")
    with pytest.raises(ComponentError, match=r"^no steady-state steer at vx = 8\.0 m/s: model matrix is singular$"):
        controller.step(0.0, state | signals)


def test_off_keeps_the_interpreted_step(jit_mode):
    jit_mode("off")
    assert step_path.compiled_step() is None
    assert BacksteppingController()._step is step_kernel.step


def test_on_without_numba_is_a_clear_error(jit_mode, monkeypatch):
    import controllers.backstepping

    jit_mode("off")
    monkeypatch.setitem(sys.modules, "controllers.backstepping.step_jit", None)   # as if numba were missing
    monkeypatch.delattr(controllers.backstepping, "step_jit", raising=False)
    monkeypatch.setenv("COSIM_JIT", "on")
    step_path.compiled_step.cache_clear()
    with pytest.raises(ImportError, match=r"COSIM_JIT=on: the compiled backstepping step needs numba "
                                          r"\(pip install 'cosim\[jit\]'\)"):
        step_path.compiled_step()
    monkeypatch.setenv("COSIM_JIT", "auto")
    step_path.compiled_step.cache_clear()
    assert step_path.compiled_step() is None


def _disagreeing(monkeypatch) -> list[str]:
    """step_jit.step made one bit off in its first output; its recompile() recorded, not run."""
    from controllers.backstepping import step_jit
    return one_bit_off(monkeypatch, step_jit, "step")


def test_a_step_that_disagrees_is_compiled_afresh_once_then_not_used(jit_mode, monkeypatch):
    jit_mode("off")
    calls = _disagreeing(monkeypatch)
    monkeypatch.setenv("COSIM_JIT", "auto")
    step_path.compiled_step.cache_clear()
    with pytest.warns(RuntimeWarning, match=r"the compiled backstepping step is not used: on \("):
        assert step_path.compiled_step() is None
    assert calls == ["recompile"]
    assert BacksteppingController()._step is step_kernel.step


def test_on_with_a_step_that_disagrees_is_an_error(jit_mode, monkeypatch):
    jit_mode("off")
    _disagreeing(monkeypatch)
    monkeypatch.setenv("COSIM_JIT", "on")
    step_path.compiled_step.cache_clear()
    with pytest.raises(RuntimeError, match=r"COSIM_JIT=on: the compiled backstepping step disagrees with the "
                                           r"interpreted one: on \("):
        step_path.compiled_step()


def test_the_gate_refuses_a_step_on_the_buffer_one_bit_off(jit_mode, monkeypatch):
    from controllers.backstepping import step_jit

    jit_mode("off")
    assert_refused_after_one_recompile(monkeypatch, step_path.compiled_step, step_jit, "step_on_feet",
                                       r"the compiled backstepping step is not used: on the feet \(")
