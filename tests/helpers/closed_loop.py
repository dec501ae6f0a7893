"""Test support for the controller tests: analytic paths, windows on them, a closed-loop runner.

Paths are a straight line along world x and a left-turning circle through the
origin (heading east at the origin). A stand-in planner cuts a window of
WINDOW_POINTS points, 1 m apart, starting 5 m behind the vehicle's projection,
every `planner_period` seconds; the controller steps every dt and the linear
plant integrates with the commands held over dt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.linear_plant import LinearPlant
from controllers.trajectory import WINDOW_POINTS, TrajectoryWindow


@dataclass(frozen=True)
class LinePath:
    """The world x axis (y = 0), heading 0."""

    def point(self, sigma: np.ndarray) -> tuple[np.ndarray, ...]:
        """x, y, psi, kappa at arc lengths sigma."""
        zero = np.zeros_like(sigma)
        return sigma.copy(), zero, zero, zero

    def sigma_of(self, x: float, y: float) -> float:
        """Arc length of the projection of (x, y)."""
        return x


@dataclass(frozen=True)
class CirclePath:
    """Circle of the given radius, centre (0, radius), counter-clockwise from the origin."""

    radius: float

    def point(self, sigma: np.ndarray) -> tuple[np.ndarray, ...]:
        """x, y, psi, kappa at arc lengths sigma."""
        angle = sigma / self.radius
        return (self.radius * np.sin(angle), self.radius * (1.0 - np.cos(angle)), angle,
                np.full_like(sigma, 1.0 / self.radius))

    def sigma_of(self, x: float, y: float) -> float:
        """Arc length of the projection of (x, y) (angle in (-pi, pi])."""
        return self.radius * math.atan2(x, self.radius - y)

    def offset_of(self, x: float, y: float) -> float:
        """Signed offset of (x, y), left (inside) positive."""
        return self.radius - math.hypot(x, y - self.radius)


def make_window(path, sigma0: float, v: float = 10.0, a: float = 0.0, step: float = 1.0,
                points: int = WINDOW_POINTS) -> TrajectoryWindow:
    """Window of `points` points `step` apart on `path` from arc length sigma0, constant v and a."""
    sigma = sigma0 + step * np.arange(points, dtype=float)
    x, y, psi, kappa = path.point(sigma)
    return TrajectoryWindow(x=x, y=y, psi=psi, kappa=kappa, s=sigma - sigma0,
                            v=np.full(points, v), a=np.full(points, a))


def plant_inputs(plant: LinearPlant) -> dict[str, float]:
    """The plant-contract inputs of a controller from the linear plant's state."""
    return plant.outputs()


def run_closed_loop(controller, plant: LinearPlant, path, duration: float, dt: float = 0.01,
                    v_ref: float = 10.0, planner_period: float = 0.1, wind_fx: float = 0.0,
                    wind_fy: float = 0.0) -> dict[str, np.ndarray]:
    """Simulate controller + plant; returns every controller output and plant state per step.

    Args:
        controller: a controller Component; plant: the LinearPlant; path: LinePath or CirclePath;
        duration: simulated time [s]; dt: controller and plant step [s]; v_ref: reference speed;
        planner_period: window refresh period [s]; wind_fx, wind_fy: constant disturbances [N].
    """
    record: dict[str, list[float]] = {}
    window = None
    steps = int(round(duration / dt))
    every = int(round(planner_period / dt))
    for k in range(steps + 1):
        t = k * dt
        state = plant.outputs()
        if k % every == 0:
            window = make_window(path, path.sigma_of(state["x"], state["y"]) - 5.0, v=v_ref)
        inputs = state | window.to_signals("ref")
        outputs = controller.initialize(t, inputs) if k == 0 else controller.step(t, inputs)
        for name, value in (outputs | {f"plant_{n}": v for n, v in state.items()}).items():
            record.setdefault(name, []).append(float(value))
        record.setdefault("t", []).append(t)
        if k < steps:
            plant.step(dt, outputs["delta"], outputs["torque"], wind_fx, wind_fy)
    return {name: np.array(values) for name, values in record.items()}


def run_error_model(gains, vx: float, rho: float, duration: float, dt: float = 0.01,
                    mu: float = 1.0, mu_hat: float = 1.0, start=(0.0, 0.0, 0.0, 0.0),
                    params=None) -> dict[str, np.ndarray]:
    """Lateral law in closed loop with the paper's error model at constant speed (RK4, ZOH steer).

    Args:
        gains: LateralGains; vx: speed; rho: constant curvature; duration, dt: time span and step;
        mu: plant friction; mu_hat: friction the law uses; start: initial [yL, psiL, vy, r];
        params: VehicleParams of both law and model (default Table I).
    Returns arrays "state" (steps+1, 4), "delta", "V2" per step.
    """
    from controllers.backstepping.lateral import LateralMeasurement, lateral_law
    from controllers.linear_plant import error_derivatives
    from controllers.vehicle_params import VehicleParams

    params = params or VehicleParams()
    state = np.array(start, dtype=float)
    states, deltas, v2 = [state], [], []
    for _ in range(int(round(duration / dt))):
        meas = LateralMeasurement(*state, vx=vx, vx_dot=0.0, rho=rho, rho_dot=0.0)
        command = lateral_law(meas, mu_hat, params, gains)
        deltas.append(command.delta)
        v2.append(command.V2)

        def rate(s):
            return error_derivatives(params, s, vx, rho, command.delta, mu, gains.ls)
        k1 = rate(state)
        k2 = rate(state + 0.5 * dt * k1)
        k3 = rate(state + 0.5 * dt * k2)
        k4 = rate(state + dt * k3)
        state = state + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        states.append(state)
    return {"state": np.array(states), "delta": np.array(deltas), "V2": np.array(v2)}
