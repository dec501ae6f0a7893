"""Baseline path-tracking controllers: Pure Pursuit and Stanley, with a PI speed loop.

Same inputs and command outputs as the backstepping controller (plant
measurements, the recommended ref_* window; delta, torque), so a scenario can
swap them in its YAML. Both share the PI speed loop with feed-forward of the
reference acceleration (control_common.SpeedPI) and the same actuator limits.
For comparison plots they output the same path errors: yL and psiL at the
preview point ls ahead of the CG (not used by their laws), yc = yL - ls psiL and
yc_cg (the CG's geometric offset) at the CG, ex,
vx_ref.

Pure Pursuit (geometric, rear axle): the target is the path point a look-ahead
distance ld = max(ld_min, ld_gain vx) along the window beyond the rear axle's
foot point; with alpha the target's bearing from the vehicle heading and d its
distance, delta = atan(2 L sin(alpha) / d), L = lf + lr.

Stanley (front axle): with psi_e = path heading - psi at the front axle's foot
point and e its signed offset (left positive),
delta = psi_e + atan(-k_stanley e / (k_soft + vx)).

No trajectory yet (an all-zero window): steering held, torque 0, internals 0.

SpeedLoop is the speed half alone, for a vehicle driven by a scripted speed
(the lead of scenarios/vehicle_following.yaml): the same PI on torque, its
reference v_ref from any source (a table over time), the feed-forward
acceleration the finite difference of v_ref between two steps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from cosim.component import Component, ComponentError, ModelReference, Port, Value
from controllers.tracking import (COMMAND_OUTPUTS, CONTROLLER_INPUTS, ActuatorLimits,
                                        InputReader, SpeedPI, SteeringLimiter, StepClock,
                                        empty_window_outputs, finite_outputs, path_errors)
from controllers.vehicle_params import VehicleParams
from controllers.road.projection import PreparedWindow, foot, point_at, wrap_angle

OUTPUT_NAMES: tuple[str, ...] = tuple(port.name for port in COMMAND_OUTPUTS)
SLOT = 2      # the PreparedWindow tracking slot of the steering law's own projection point


class _BaselineController(Component):
    """Common step of the baselines: checks, speed loop, limits, outputs; subclasses steer."""

    inputs = CONTROLLER_INPUTS
    outputs = COMMAND_OUTPUTS
    default_period = 0.01

    def __init__(self, m: float, iy: float, Rw: float, lf: float, lr: float, ls: float,
                 kp: float, ki: float, max_delta: float, max_delta_rate: float,
                 max_torque: float, min_torque: float, period: float) -> None:
        self.params = VehicleParams(m=m, iy=iy, Rw=Rw, lf=lf, lr=lr)
        if not ls >= 0.0:
            raise ComponentError(f"ls must be >= 0, got {ls!r}")
        self.ls = float(ls)
        self.limits = ActuatorLimits(max_delta, max_delta_rate, max_torque, min_torque)
        self.steering = SteeringLimiter(self.limits)
        self.speed = SpeedPI(kp, ki, self.params.me, self.params.Rw, self.limits)
        self.clock = StepClock(period)
        self.reader = InputReader()

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """One control step at time t."""
        dt = self.clock.advance(t)
        plant, window = self.reader.read(inputs, t)
        if window is None:
            return empty_window_outputs(self.outputs, self.steering.last)
        x, y, psi, vx = plant[:4]
        y_l, psi_l, y_c, y_cg, _, _, vx_ref, vx_ref_dot, *_ = path_errors(
            window, x, y, psi, vx, self.ls)
        ex = vx - vx_ref
        torque = self.speed.torque(ex, vx_ref_dot, dt)
        delta = self.steering.apply(self.steer(plant, window), dt)
        return finite_outputs(OUTPUT_NAMES, (delta, torque, y_l, psi_l, y_c, y_cg, ex, vx_ref), t)

    def steer(self, plant: tuple[float, ...], window: PreparedWindow) -> float:
        """Steering command before limits from (x, y, psi, vx, vy, r) (subclasses)."""
        raise NotImplementedError


class PurePursuitController(_BaselineController):
    """Pure Pursuit steering + PI speed loop (see module docstring).

    Args:
        m, iy, Rw, lf, lr: nominal vehicle parameters (Table I defaults).
        ls: preview distance of the yL/psiL diagnostics [m].
        ld_min: smallest look-ahead [m] (> 0); ld_gain: look-ahead per unit speed [s] (>= 0).
        kp, ki: PI speed gains [N/(m/s)], [N/m].
        max_delta, max_delta_rate, max_torque, min_torque: actuator limits; period: first dt [s].
    """

    parameters_model = ModelReference("controllers.baseline_parameters:PurePursuitParameters")

    def __init__(self, *, m: float = 1500.0, iy: float = 1.2, Rw: float = 0.3, lf: float = 1.006,
                 lr: float = 1.462, ls: float = 5.0, ld_min: float = 4.0, ld_gain: float = 0.6,
                 kp: float = 3000.0, ki: float = 600.0, max_delta: float = 0.5,
                 max_delta_rate: float = 1.0, max_torque: float = 3000.0,
                 min_torque: float = -6000.0, period: float = 0.01) -> None:
        super().__init__(m, iy, Rw, lf, lr, ls, kp, ki, max_delta, max_delta_rate, max_torque,
                         min_torque, period)
        if not (ld_min > 0.0 and ld_gain >= 0.0):
            raise ComponentError(f"need ld_min > 0 and ld_gain >= 0, got {ld_min!r}, {ld_gain!r}")
        self.ld_min, self.ld_gain = float(ld_min), float(ld_gain)

    def steer(self, plant: tuple[float, ...], window: PreparedWindow) -> float:
        """Pure Pursuit steering angle from the rear axle towards the look-ahead point."""
        x, y, psi, vx = plant[:4]
        rear_x = x - self.params.lr * math.cos(psi)
        rear_y = y - self.params.lr * math.sin(psi)
        look_ahead = max(self.ld_min, self.ld_gain * vx)
        at_rear = foot(window, rear_x, rear_y, SLOT)
        target_x, target_y = point_at(window, at_rear[0] + look_ahead)
        distance = math.hypot(target_x - rear_x, target_y - rear_y)
        bearing = wrap_angle(math.atan2(target_y - rear_y, target_x - rear_x) - psi)
        return math.atan(2.0 * self.params.wheelbase * math.sin(bearing) / max(distance, 1e-6))


class StanleyController(_BaselineController):
    """Stanley steering + PI speed loop (see module docstring).

    Args:
        m, iy, Rw, lf, lr: nominal vehicle parameters (Table I defaults).
        ls: preview distance of the yL/psiL diagnostics [m].
        k_stanley: cross-track gain [1/s] (> 0); k_soft: speed softening [m/s] (> 0).
        kp, ki: PI speed gains [N/(m/s)], [N/m].
        max_delta, max_delta_rate, max_torque, min_torque: actuator limits; period: first dt [s].
    """

    parameters_model = ModelReference("controllers.baseline_parameters:StanleyParameters")

    def __init__(self, *, m: float = 1500.0, iy: float = 1.2, Rw: float = 0.3, lf: float = 1.006,
                 lr: float = 1.462, ls: float = 5.0, k_stanley: float = 1.0, k_soft: float = 1.0,
                 kp: float = 3000.0, ki: float = 600.0, max_delta: float = 0.5,
                 max_delta_rate: float = 1.0, max_torque: float = 3000.0,
                 min_torque: float = -6000.0, period: float = 0.01) -> None:
        super().__init__(m, iy, Rw, lf, lr, ls, kp, ki, max_delta, max_delta_rate, max_torque,
                         min_torque, period)
        if not (k_stanley > 0.0 and k_soft > 0.0):
            raise ComponentError(f"need k_stanley > 0 and k_soft > 0, got {k_stanley!r}, {k_soft!r}")
        self.k_stanley, self.k_soft = float(k_stanley), float(k_soft)

    def steer(self, plant: tuple[float, ...], window: PreparedWindow) -> float:
        """Stanley steering angle from the front axle's heading and cross-track errors."""
        x, y, psi, vx = plant[:4]
        front = foot(window, x + self.params.lf * math.cos(psi), y + self.params.lf * math.sin(psi), SLOT)
        heading_error = wrap_angle(front[4] - psi)
        return heading_error + math.atan(-self.k_stanley * front[3] / (self.k_soft + vx))


class SpeedLoop(Component):
    """PI speed loop on torque for a scripted speed reference (see module docstring).

    Args:
        m, iy, Rw: nominal vehicle parameters (Table I defaults) for the feed-forward.
        kp, ki: PI speed gains [N/(m/s)], [N/m].
        max_torque, min_torque: torque limits [N.m]; period: first dt [s].
    """

    inputs = (Port("vx", unit="m/s", description="longitudinal speed, body axes"),
              Port("v_ref", unit="m/s", description="speed reference"))
    outputs = (Port("torque", unit="N.m", description="total wheel torque command"),
               Port("ex", unit="m/s", description="speed error vx - v_ref"))
    default_period = 0.01
    parameters_model = ModelReference("controllers.baseline_parameters:SpeedLoopParameters")

    def __init__(self, *, m: float = 1500.0, iy: float = 1.2, Rw: float = 0.3, kp: float = 3000.0,
                 ki: float = 600.0, max_torque: float = 3000.0, min_torque: float = -6000.0,
                 period: float = 0.01) -> None:
        params = VehicleParams(m=m, iy=iy, Rw=Rw)
        self.speed = SpeedPI(kp, ki, params.me, params.Rw, ActuatorLimits(min_torque=min_torque,
                                                                           max_torque=max_torque))
        self.clock = StepClock(period)
        self.v_prev: float | None = None

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """One step: torque for the error vx - v_ref with the reference's slope fed forward."""
        dt = self.clock.advance(t)
        vx, v_ref = float(inputs["vx"]), float(inputs["v_ref"])
        a_ref = 0.0 if self.v_prev is None else (v_ref - self.v_prev) / dt
        self.v_prev = v_ref
        ex = vx - v_ref
        return finite_outputs(("torque", "ex"), (self.speed.torque(ex, a_ref, dt), ex), t)
