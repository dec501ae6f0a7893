"""Plumbing shared by the path-tracking controller components.

Ports (plant measurements and the recommended trajectory window), input
checks with clear messages, the step clock (dt from consecutive t values),
path errors at the preview point, actuator limits (steer angle and rate,
torque) and the PI speed loop of the baselines. No control law lives here.

Path errors: the preview point P = CG + ls [cos psi, sin psi] is projected on
the window; yL is P's signed offset (left of the path positive), psiL =
psi - path heading at P's foot (wrapped), rho the curvature there and
rho_dot = dkappa/ds * vx. To first order these obey the paper's error model
(yL_dot = vy + vx psiL + ls r, psiL_dot = r - vx rho). yc is the CG's own
signed offset from its foot point (the paper's yL - ls psiL is its linear
approximation, which misses ls^2 rho / 2 on a curve). The reference speed and
acceleration are read at the CG's foot point.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from cosim.component import ComponentError, Port, Value
from controllers.trajectory import TrajectoryWindow, window_ports
from controllers.window_projection import (PreparedWindow, WindowError, is_empty, project,
                                           validate_window, wrap_angle)

PLANT_INPUTS: tuple[Port, ...] = (
    Port("x", unit="m", description="CG world x"),
    Port("y", unit="m", description="CG world y"),
    Port("psi", unit="rad", description="yaw angle"),
    Port("vx", unit="m/s", description="longitudinal speed, body axes"),
    Port("vy", unit="m/s", description="lateral speed, body axes"),
    Port("r", unit="rad/s", description="yaw rate"),
)
CONTROLLER_INPUTS: tuple[Port, ...] = PLANT_INPUTS + window_ports("ref", role="recommended")
COMMAND_OUTPUTS: tuple[Port, ...] = (
    Port("delta", unit="rad", description="front road-wheel steering angle command"),
    Port("torque", unit="N.m", description="total wheel torque command"),
    Port("yL", unit="m", description="lateral error at the preview point, left positive"),
    Port("psiL", unit="rad", description="heading error at the preview point"),
    Port("yc", unit="m", description="lateral error at the CG, left positive"),
    Port("ex", unit="m/s", description="speed error vx - vx_ref"),
    Port("vx_ref", unit="m/s", description="reference speed at the CG's foot point"),
)


@dataclass(frozen=True)
class PlantMeasurement:
    """The plant outputs a controller reads."""

    x: float
    y: float
    psi: float
    vx: float
    vy: float
    r: float


@dataclass(frozen=True)
class PathErrors:
    """Errors and reference read from the window (see module docstring)."""

    y_l: float
    psi_l: float
    y_c: float
    rho: float
    rho_dot: float
    vx_ref: float
    vx_ref_dot: float


def read_inputs(inputs: Mapping[str, Value], t: float) -> tuple[PlantMeasurement, TrajectoryWindow]:
    """Check and unpack a controller's inputs; ComponentError names the port, time and value.

    Args:
        inputs: the step's input mapping (PLANT_INPUTS and the ref_* window).
        t: the step's time, for messages.
    """
    values = {}
    for port in PLANT_INPUTS:
        value = float(inputs[port.name])
        if not math.isfinite(value):
            raise ComponentError(f"input {port.name!r} is not finite at t = {t}: {value}")
        values[port.name] = value
    window = TrajectoryWindow.from_signals(inputs, "ref")
    if not is_empty(window):
        try:
            validate_window(window, "ref")
        except WindowError as error:
            raise ComponentError(f"bad trajectory window at t = {t}: {error}") from None
    return PlantMeasurement(**values), window


def path_errors(window: TrajectoryWindow | PreparedWindow, plant: PlantMeasurement, ls: float) -> PathErrors:
    """Errors at the preview point and the reference speed at the CG's foot point.

    Args:
        window: a valid, non-empty trajectory window (or a PreparedWindow of it).
        plant: the measured state.
        ls: preview distance [m].
    """
    window = window if isinstance(window, PreparedWindow) else PreparedWindow(window)
    cos_psi, sin_psi = math.cos(plant.psi), math.sin(plant.psi)
    preview = project(window, plant.x + ls * cos_psi, plant.y + ls * sin_psi)
    at_cg = project(window, plant.x, plant.y)
    psi_l = wrap_angle(plant.psi - preview.psi_path)
    return PathErrors(y_l=preview.offset, psi_l=psi_l, y_c=at_cg.offset,
                      rho=preview.kappa, rho_dot=preview.dkappa_ds * plant.vx,
                      vx_ref=at_cg.v, vx_ref_dot=at_cg.a)


class StepClock:
    """dt between consecutive step times; the first step uses the nominal period.

    Args:
        period: nominal step period [s] (> 0).
    """

    def __init__(self, period: float) -> None:
        if not period > 0.0:
            raise ComponentError(f"period must be > 0, got {period!r}")
        self.period = float(period)
        self.last_t: float | None = None

    def advance(self, t: float) -> float:
        """Return dt for a step at time t (ComponentError if time does not increase)."""
        dt = self.period if self.last_t is None else t - self.last_t
        if not dt > 0.0:
            raise ComponentError(f"step time must increase: t = {t} after t = {self.last_t}")
        self.last_t = t
        return dt


@dataclass(frozen=True)
class ActuatorLimits:
    """Steering angle and rate, torque limits.

    Args:
        max_delta: steering angle bound [rad] (> 0); max_delta_rate: steering rate bound [rad/s] (> 0);
        max_torque: largest drive torque [N.m]; min_torque: most negative (braking) torque [N.m].
    """

    max_delta: float = 0.5
    max_delta_rate: float = 1.0
    max_torque: float = 3000.0
    min_torque: float = -6000.0

    def __post_init__(self) -> None:
        if not self.max_delta > 0.0:
            raise ComponentError(f"max_delta must be > 0, got {self.max_delta!r}")
        if not self.max_delta_rate > 0.0:
            raise ComponentError(f"max_delta_rate must be > 0, got {self.max_delta_rate!r}")
        if not self.min_torque < self.max_torque:
            raise ComponentError(f"min_torque ({self.min_torque!r}) must be < max_torque ({self.max_torque!r})")

    def torque(self, command: float) -> float:
        """Clip a torque command to [min_torque, max_torque]."""
        return min(self.max_torque, max(self.min_torque, command))


class SteeringLimiter:
    """Applies the angle and rate limits to steering commands; remembers the last output.

    Args:
        limits: the actuator limits; initial: steering angle before the first step [rad].
    """

    def __init__(self, limits: ActuatorLimits, initial: float = 0.0) -> None:
        self.limits = limits
        self.last = float(initial)

    def apply(self, command: float, dt: float) -> float:
        """Limited steering angle for a command over a step of dt seconds."""
        step = self.limits.max_delta_rate * dt
        delta = min(self.last + step, max(self.last - step, command))
        delta = min(self.limits.max_delta, max(-self.limits.max_delta, delta))
        self.last = delta
        return delta


class SpeedPI:
    """PI speed loop with feed-forward of the reference acceleration (baselines).

        torque = Rw ( me a_ref - kp ex - ki integral(ex) )

    The integral is frozen while the torque saturates in the direction that
    would grow it (conditional integration, no wind-up).

    Args:
        kp: proportional gain [N/(m/s)]; ki: integral gain [N/m]; me: equivalent mass [kg];
        rw: wheel radius [m]; limits: actuator limits.
    """

    def __init__(self, kp: float, ki: float, me: float, rw: float, limits: ActuatorLimits) -> None:
        if not kp > 0.0 or not ki >= 0.0:
            raise ComponentError(f"speed loop gains need kp > 0 and ki >= 0, got kp={kp!r}, ki={ki!r}")
        self.kp, self.ki, self.me, self.rw, self.limits = kp, ki, me, rw, limits
        self.integral = 0.0

    def torque(self, ex: float, a_ref: float, dt: float) -> float:
        """Saturated torque for speed error ex, reference acceleration a_ref, step dt."""
        candidate = self.integral + ex * dt
        command = self.rw * (self.me * a_ref - self.kp * ex - self.ki * candidate)
        applied = self.limits.torque(command)
        pushing_further = (command > applied and ex < 0.0) or (command < applied and ex > 0.0)
        if not pushing_further:
            self.integral = candidate
        return applied


def outputs_to_floats(values: Mapping[str, float]) -> dict[str, float]:
    """Convert every value to a Python float, refusing non-finite ones (ComponentError)."""
    result = {}
    for name, value in values.items():
        value = float(value)
        if not math.isfinite(value):
            raise ComponentError(f"output {name!r} is not finite: {value}")
        result[name] = value
    return result


def empty_window_outputs(names: tuple[Port, ...], delta: float) -> dict[str, float]:
    """Outputs while no trajectory has arrived: hold the steer, zero torque, zero internals."""
    values = {port.name: 0.0 for port in names}
    values["delta"] = delta
    return values


__all__ = ["ActuatorLimits", "COMMAND_OUTPUTS", "CONTROLLER_INPUTS", "PLANT_INPUTS", "PathErrors",
           "PlantMeasurement", "SpeedPI", "SteeringLimiter", "StepClock", "empty_window_outputs",
           "outputs_to_floats", "path_errors", "read_inputs"]
