"""Pure Pursuit and Stanley baselines with the PI speed loop, and the speed loop alone, on the linear plant."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.baselines import PurePursuitController, SpeedLoop, StanleyController
from controllers.linear_plant import LinearPlant
from controllers.vehicle_params import VehicleParams
from cosim.component import ComponentError
from tests.helpers.closed_loop import CirclePath, LinePath, make_window, run_closed_loop

PARAMS = VehicleParams()
BASELINES = [PurePursuitController, StanleyController]


def test_same_ports_as_backstepping():
    reference = BacksteppingController()
    for cls in BASELINES:
        controller = cls()
        assert controller.inputs == reference.inputs
        names = [port.name for port in controller.outputs]
        assert names == ["delta", "torque", "yL", "psiL", "yc", "yc_cg", "ex", "vx_ref"]
        assert all(name in [port.name for port in reference.outputs] for name in names)


@pytest.mark.parametrize("cls", BASELINES)
def test_straight_line_from_offset(cls):
    plant = LinearPlant(PARAMS, y0=1.0, psi0=-0.05, vx0=8.0, cx=0.42, substeps=2)
    run = run_closed_loop(cls(), plant, LinePath(), duration=10.0, v_ref=10.0)
    assert run["yc_cg"][0] == pytest.approx(1.0)
    assert run["yc"][0] == pytest.approx(run["yL"][0] - 5.0 * run["psiL"][0])
    assert np.max(np.abs(run["yc"][500:])) < 0.03        # settled after 5 s
    assert abs(run["yc"][-1]) < 0.005
    assert abs(run["ex"][-1]) < 0.05                      # the integral absorbs the drag
    assert np.all(np.diff(np.abs(run["ex"][300::100])) < 0.0)   # PI decays once the speed is reached


@pytest.mark.parametrize("cls, tolerance", [(PurePursuitController, 0.1), (StanleyController, 0.1)])
def test_circle_tracking_within_tolerance(cls, tolerance):
    radius = 100.0
    plant = LinearPlant(PARAMS, vx0=10.0, r0=10.0 / radius, substeps=2)
    run = run_closed_loop(cls(), plant, CirclePath(radius), duration=12.0, v_ref=10.0)
    cg_offsets = [CirclePath(radius).offset_of(x, y) for x, y in zip(run["plant_x"], run["plant_y"])]
    assert run["yc_cg"] == pytest.approx(np.array(cg_offsets), abs=1e-8)   # Hermite vs exact circle
    assert np.max(np.abs(run["yc_cg"][600:])) < tolerance
    # steering settles near the steady-state steer of the model (L + K vx^2) rho
    understeer = PARAMS.m / PARAMS.wheelbase * (PARAMS.lr / (2 * PARAMS.Cf) - PARAMS.lf / (2 * PARAMS.Cr))
    assert run["delta"][-1] == pytest.approx((PARAMS.wheelbase + understeer * 100.0) / radius, rel=0.05)


@pytest.mark.parametrize("cls", BASELINES)
def test_limits_respected(cls):
    controller = cls(max_delta=0.04, max_delta_rate=0.2, max_torque=300.0, min_torque=-200.0)
    plant = LinearPlant(PARAMS, y0=-3.0, vx0=6.0, substeps=2)
    run = run_closed_loop(controller, plant, LinePath(), duration=3.0, v_ref=10.0)
    assert np.max(np.abs(run["delta"])) == pytest.approx(0.04)
    assert np.max(np.abs(np.diff(run["delta"]))) <= 0.2 * 0.01 + 1e-15
    assert np.max(run["torque"]) == 300.0 and np.min(run["torque"]) >= -200.0


def test_pure_pursuit_steer_on_a_circle_is_the_geometric_arc():
    # rear axle on the circle, heading tangent: the arc through the target has curvature 1/R,
    # so delta = atan(L / R) exactly (chord geometry), whatever the look-ahead
    radius = 40.0
    path = CirclePath(radius)
    window = make_window(path, -10.0)
    rear_sigma = 3.0
    angle = rear_sigma / radius
    rear_x, rear_y = radius * math.sin(angle), radius * (1 - math.cos(angle))
    x = rear_x + PARAMS.lr * math.cos(angle)
    y = rear_y + PARAMS.lr * math.sin(angle)
    out = PurePursuitController(max_delta_rate=100.0).step(
        0.0, {"x": x, "y": y, "psi": angle, "vx": 10.0, "vy": 0.0, "r": 0.0} | window.to_signals("ref"))
    assert out["delta"] == pytest.approx(math.atan(PARAMS.wheelbase / radius), abs=1e-6)


def test_stanley_steer_formula():
    window = make_window(LinePath(), -10.0)
    controller = StanleyController(k_stanley=2.0, k_soft=1.0, max_delta_rate=100.0)
    # front axle 0.5 m left of the line, heading 0.02 rad: delta = -0.02 + atan(-2 * 0.5 / 11)
    y = 0.5 - PARAMS.lf * math.sin(0.02)
    out = controller.step(0.0, {"x": 0.0, "y": y, "psi": 0.02, "vx": 10.0, "vy": 0.0, "r": 0.0}
                          | window.to_signals("ref"))
    assert out["delta"] == pytest.approx(-0.02 + math.atan(-1.0 / 11.0), abs=1e-12)


def test_bad_parameters():
    with pytest.raises(ComponentError, match="need ld_min > 0"):
        PurePursuitController(ld_min=0.0)
    with pytest.raises(ComponentError, match="need k_stanley > 0"):
        StanleyController(k_stanley=-1.0)
    with pytest.raises(ComponentError, match="speed loop gains need kp > 0"):
        StanleyController(kp=0.0)


def _speed_loop_run(reference, seconds: float, vx0: float, cx: float = 0.42):
    """SpeedLoop alone on the linear plant driving straight; (t, vx, v_ref) per 10 ms step."""
    loop, plant = SpeedLoop(), LinearPlant(PARAMS, vx0=vx0, cx=cx, substeps=2)
    rows = []
    for k in range(int(round(seconds / 0.01)) + 1):
        t = 0.01 * k
        vx = plant.outputs()["vx"]
        out = loop.step(t, {"vx": vx, "v_ref": reference(t)})
        assert out["ex"] == vx - reference(t)
        rows.append((t, vx, reference(t)))
        plant.step(0.01, 0.0, out["torque"])
    return np.array(rows).T


def test_speed_loop_tracks_a_ramp_with_its_slope_fed_forward():
    """A 0.5 m/s2 ramp from 8 to 13 m/s: the feed-forward and the integral leave no lag at the end."""
    t, vx, ref = _speed_loop_run(lambda t: float(np.interp(t, [0, 5, 15], [8, 8, 13])), 25.0, vx0=8.0)
    ramp = (t > 8.0) & (t < 15.0)
    assert np.max(np.abs(vx[ramp] - ref[ramp])) < 0.05
    assert abs(vx[-1] - 13.0) < 1e-3


def test_speed_loop_refuses_bad_gains():
    with pytest.raises(ComponentError, match="kp > 0"):
        SpeedLoop(kp=0.0)
