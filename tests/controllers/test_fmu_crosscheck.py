"""Cross-checks between the controllers' Python model and the Bicycle FMU.

The controller's nominal parameters must default to the FMU's (Table I plus
the chosen lw), and controllers.linear_plant (RK4, 1 ms sub-steps) must give
the same closed-loop trajectory as the Bicycle FMU (RK4, sub-steps <= 1 ms)
driven by the same controller: two implementations of EQUATIONS.md.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.linear_plant import LinearPlant
from controllers.vehicle_params import VehicleParams
from tests.helpers.closed_loop import CirclePath, make_window
from tests.helpers.fmus import Plant, built_fmu, parse_variables_def
from tests.helpers.paths import REPO_ROOT

BICYCLE_DEF = REPO_ROOT / "fmus" / "Bicycle" / "variables.def"
STATE = ["x", "y", "psi", "vx", "vy", "r"]


def test_nominal_parameters_match_the_bicycle_fmu_defaults():
    starts = {row["name"]: row["start"] for row in parse_variables_def(BICYCLE_DEF)}
    for field in fields(VehicleParams):
        assert getattr(VehicleParams(), field.name) == starts[field.name], field.name


def closed_loop(step_plant, read_state, duration: float, dt: float = 0.01) -> np.ndarray:
    """Adaptive feedforward controller on a circle; returns the plant state per tick."""
    controller = BacksteppingController(lateral_law="feedforward", adaptive=True, mu0=0.9)
    path = CirclePath(60.0)
    rows = []
    for k in range(int(round(duration / dt)) + 1):
        state = read_state()
        rows.append([state[name] for name in STATE])
        window = make_window(path, path.sigma_of(state["x"], state["y"]) - 5.0, v=11.0)
        inputs = state | window.to_signals("ref")
        out = controller.initialize(0.0, inputs) if k == 0 else controller.step(k * dt, inputs)
        step_plant(k * dt, dt, out["delta"], out["torque"])
    return np.array(rows)


def test_linear_plant_matches_bicycle_fmu_in_closed_loop(fmu_dir):
    path, unzip = built_fmu(fmu_dir, "Bicycle", 2)
    fmu = Plant(path, unzip)
    start = {"y0": 0.5, "vx0": 9.0}
    fmu.init(start)
    fmu.set({"mu": 0.8, "wind_fx": 0.0, "wind_fy": 150.0})

    def fmu_step(t, dt, delta, torque):
        fmu.set({"delta": delta, "torque": torque})
        fmu.do_step(t, dt)

    try:
        from_fmu = closed_loop(fmu_step, lambda: dict(zip(STATE, fmu.get(STATE))), duration=4.0)
    finally:
        fmu.free()
    python = LinearPlant(VehicleParams(), y0=0.5, vx0=9.0, mu=0.8, cx=0.42, substeps=10)

    def python_step(t, dt, delta, torque):
        python.step(dt, delta, torque, wind_fx=0.0, wind_fy=150.0)

    from_python = closed_loop(python_step, python.outputs, duration=4.0)
    assert np.max(np.abs(from_python[:, 1])) > 0.4           # the car did turn
    assert from_python == pytest.approx(from_fmu, rel=1e-12, abs=1e-12)   # measured: <= 7e-15
