"""Pure-Python linear bicycle + equivalent-wheel vehicle of EQUATIONS.md.

Two uses: the plant of the controllers' unit tests (no FMU, no transport), and
a second implementation to cross-check the Bicycle FMU against. State, world
frame and body axes as in the plant contract of DESIGN.md:

    vy_dot, r_dot = (mu A1(vx) + A2(vx)) [vy, r] + mu B delta + D Fwy
    vx_dot        = (torque / Rw + m vy r + Fwx) / me,   Fwx = wind_fx - cx vx^2
    x_dot = vx cos psi - vy sin psi,  y_dot = vx sin psi + vy cos psi,  psi_dot = r

Inputs are held constant over a step, integrated by classical RK4 with a fixed
number of sub-steps, so a run is deterministic. The model divides by vx: it is
valid for vx > 0 only and refuses to step at vx <= V_MIN_PLANT.

`error_derivatives` gives the paper's path-error model (yL, psiL on a road of
constant or slowly varying curvature rho) coupled to the same lateral dynamics,
for analyses in error coordinates.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.vehicle_params import VehicleParams

V_MIN_PLANT = 0.1
STATE_NAMES = ("x", "y", "psi", "vx", "vy", "r")


class LinearPlant:
    """World-frame linear vehicle model (see module docstring).

    Args:
        params: the plant's parameters (may differ from the controller's nominal ones).
        x0, y0, psi0, vx0, vy0, r0: initial state.
        mu: road friction coefficient.
        cx: aerodynamic drag coefficient [N s^2/m^2], Fwx includes -cx vx^2.
        substeps: RK4 sub-steps per call to step.
    """

    def __init__(self, params: VehicleParams, x0: float = 0.0, y0: float = 0.0, psi0: float = 0.0,
                 vx0: float = 10.0, vy0: float = 0.0, r0: float = 0.0, mu: float = 1.0,
                 cx: float = 0.0, substeps: int = 4) -> None:
        self.params = params
        self.state = np.array([x0, y0, psi0, vx0, vy0, r0], dtype=float)
        self.mu = float(mu)
        self.cx = float(cx)
        self.substeps = int(substeps)

    def derivatives(self, state: np.ndarray, delta: float, torque: float,
                    wind_fx: float = 0.0, wind_fy: float = 0.0) -> np.ndarray:
        """Time derivative of the state [x, y, psi, vx, vy, r] for the given inputs.

        Args:
            state: the 6-vector state.
            delta: front steering angle [rad]; torque: total wheel torque [N.m];
            wind_fx, wind_fy: extra longitudinal force at the CG and side force at lw [N].
        """
        p, mu = self.params, self.mu
        _, _, psi, vx, vy, r = state.tolist()
        # Scalar form of (mu A1 + A2) x + mu B delta + D Fwy (numpy is slow on 2-vectors).
        cf2, cr2 = 2.0 * p.Cf, 2.0 * p.Cr
        cross = cr2 * p.lr - cf2 * p.lf
        vy_dot = (mu * (-(cf2 + cr2) * vy + cross * r) / vx + mu * cf2 * delta + wind_fy) / p.m - vx * r
        r_dot = (mu * (cross * vy - (cf2 * p.lf**2 + cr2 * p.lr**2) * r) / vx
                 + mu * cf2 * p.lf * delta + p.lw * wind_fy) / p.Iz
        fwx = wind_fx - self.cx * vx * vx
        vx_dot = (torque / p.Rw + p.m * vy * r + fwx) / p.me
        cos_psi, sin_psi = math.cos(psi), math.sin(psi)
        return np.array([vx * cos_psi - vy * sin_psi, vx * sin_psi + vy * cos_psi,
                         r, vx_dot, vy_dot, r_dot])

    def step(self, dt: float, delta: float, torque: float,
             wind_fx: float = 0.0, wind_fy: float = 0.0) -> None:
        """Advance the state by dt with inputs held constant (RK4, `substeps` sub-steps)."""
        if self.state[3] <= V_MIN_PLANT:
            raise ValueError(f"linear plant: vx = {self.state[3]} m/s is below {V_MIN_PLANT} m/s")
        h = dt / self.substeps
        args = (delta, torque, wind_fx, wind_fy)
        for _ in range(self.substeps):
            s = self.state
            k1 = self.derivatives(s, *args)
            k2 = self.derivatives(s + 0.5 * h * k1, *args)
            k3 = self.derivatives(s + 0.5 * h * k2, *args)
            k4 = self.derivatives(s + h * k3, *args)
            self.state = s + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def outputs(self) -> dict[str, float]:
        """The plant-contract outputs x, y, psi, vx, vy, r as floats."""
        return {name: float(value) for name, value in zip(STATE_NAMES, self.state)}


def error_derivatives(params: VehicleParams, state: np.ndarray, vx: float, rho: float, delta: float,
                      mu: float, ls: float, wind_fy: float = 0.0) -> np.ndarray:
    """Derivative of [yL, psiL, vy, r] in the paper's path-error model at constant speed vx.

        yL_dot = vy + vx psiL + ls r,   psiL_dot = r - vx rho,
        [vy, r]_dot = (mu A1 + A2) [vy, r] + mu B delta + D Fwy

    Args:
        params: vehicle parameters; state: [yL, psiL, vy, r]; vx: speed [m/s];
        rho: road curvature [1/m]; delta: steering angle [rad]; mu: friction;
        ls: preview distance [m]; wind_fy: side-wind force [N].
    """
    y_l, psi_l, vy, r = state
    lateral = params.a(vx, mu) @ np.array([vy, r]) + mu * params.b() * delta + params.d() * wind_fy
    return np.array([vy + vx * psi_l + ls * r, r - vx * rho, lateral[0], lateral[1]])
