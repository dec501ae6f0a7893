"""The pure-Python linear plant and the model equilibrium against closed-form solutions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.backstepping.lateral import steady_state_per_curvature
from controllers.linear_plant import LinearPlant, error_derivatives
from controllers.vehicle_params import VehicleParams
from cosim.component import ComponentError

PARAMS = VehicleParams()


def test_constant_torque_gives_linear_speed():
    plant = LinearPlant(PARAMS, vx0=5.0)
    for _ in range(100):
        plant.step(0.01, delta=0.0, torque=600.0)
    expected_vx = 5.0 + 600.0 / (PARAMS.Rw * PARAMS.me) * 1.0
    assert plant.state[3] == pytest.approx(expected_vx, rel=1e-12)
    assert plant.state[0] == pytest.approx(5.0 + 0.5 * (expected_vx - 5.0), rel=1e-12)
    assert plant.state[1] == 0.0 and plant.state[2] == 0.0


def test_drag_decay_matches_closed_form():
    cx = 0.42
    plant = LinearPlant(PARAMS, vx0=14.0, cx=cx)
    for _ in range(200):
        plant.step(0.05, delta=0.0, torque=0.0)
    # me vx_dot = -cx vx^2  =>  vx = vx0 / (1 + cx vx0 t / me)
    assert plant.state[3] == pytest.approx(14.0 / (1.0 + cx * 14.0 * 10.0 / PARAMS.me), rel=1e-10)


@pytest.mark.parametrize("vx, mu", [(5.0, 1.0), (10.0, 1.0), (14.0, 0.6)])
def test_steady_cornering_matches_understeer_formula(vx, mu):
    rho = 0.01
    psi_l, vy, r, delta = rho * steady_state_per_curvature(PARAMS, vx, mu, ls=5.0)
    cf_axle, cr_axle = 2.0 * mu * PARAMS.Cf, 2.0 * mu * PARAMS.Cr
    understeer = PARAMS.m / PARAMS.wheelbase * (PARAMS.lr / cf_axle - PARAMS.lf / cr_axle)
    assert delta == pytest.approx(rho * (PARAMS.wheelbase + understeer * vx**2), rel=1e-9)
    assert r == pytest.approx(vx * rho, rel=1e-12)
    assert psi_l == pytest.approx(-(vy + 5.0 * r) / vx, rel=1e-12)
    # the world-frame plant held at that steer settles on the same yaw rate and side slip
    plant = LinearPlant(PARAMS, vx0=vx, mu=mu)
    for _ in range(1000):
        plant.step(0.01, delta=delta, torque=PARAMS.Rw * -PARAMS.m * plant.state[4] * plant.state[5])
    # the held torque cancels m vy r only approximately: compare at the speed actually reached
    assert plant.state[3] == pytest.approx(vx, rel=1e-4)
    _, vy_end, r_end, delta_end = rho * steady_state_per_curvature(PARAMS, plant.state[3], mu, ls=5.0)
    scale = delta / delta_end
    assert plant.state[5] == pytest.approx(r_end * scale, rel=1e-7)
    assert plant.state[4] == pytest.approx(vy_end * scale, rel=1e-7)


def test_error_model_is_consistent_with_world_plant_on_a_line():
    # On a straight road (rho = 0) psiL = psi and yL = y + ls sin(psi) exactly; compare derivatives.
    plant = LinearPlant(PARAMS, y0=0.3, psi0=0.02, vx0=10.0, vy0=0.1, r0=0.05)
    state = plant.state
    world = plant.derivatives(state, delta=0.03, torque=0.0)
    errors = error_derivatives(PARAMS, np.array([0.3 + 5.0 * 0.02, 0.02, 0.1, 0.05]), vx=10.0,
                               rho=0.0, delta=0.03, mu=1.0, ls=5.0)
    assert errors[2:] == pytest.approx(world[4:], rel=1e-12)
    assert errors[1] == pytest.approx(world[2], rel=1e-12)
    # yL_dot = y_dot + ls cos(psi) r, which the linear model takes with cos(psi) = 1, sin(psi) = psi
    exact = world[1] + 5.0 * math.cos(0.02) * world[2]
    assert errors[0] == pytest.approx(exact, abs=3e-3)


def test_bad_vehicle_parameter_is_named():
    with pytest.raises(ComponentError, match="'m' must be > 0, got -1"):
        VehicleParams(m=-1.0)
    with pytest.raises(ComponentError, match="'Iz' must be a finite number"):
        VehicleParams(Iz=float("nan"))


def test_plant_refuses_standstill():
    plant = LinearPlant(PARAMS, vx0=0.05)
    with pytest.raises(ValueError, match="vx = 0.05 m/s is below"):
        plant.step(0.01, 0.0, 0.0)
