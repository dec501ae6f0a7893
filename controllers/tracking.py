"""Plumbing shared by the path-tracking controller components.

Ports (plant measurements and the recommended trajectory window), input
checks with clear messages, the step clock (dt from consecutive t values),
path errors at the preview point, actuator limits (steer angle and rate,
torque) and the PI speed loop of the baselines. No control law lives here.
This is every controller's per-tick path: the window is checked and prepared
once per new window (InputReader), values travel as tuples of floats.

Path errors: the preview point P = CG + ls [cos psi, sin psi] is projected on
the window; yL is P's signed offset (left of the path positive), psiL =
psi - path heading at P's foot (wrapped), rho the curvature there and
rho_dot = dkappa/ds * vx. To first order these obey the paper's error model
(yL_dot = vy + vx psiL + ls r, psiL_dot = r - vx rho). Two lateral errors at
the CG: yc = yL - ls psiL, the paper's definition (Fig. 4.7), and yc_cg, the
CG's own signed offset from its foot point on the path (geometric; yc is its
linear approximation, which misses about ls^2 rho / 2 on a curve). The
reference speed and acceleration are read at the CG's foot point.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cosim.component import ComponentError, Port, Value, is_frozen
from controllers import jit
from controllers.trajectory import FIELDS, TrajectoryWindow, window_ports
from controllers.road.projection import (PreparedWindow, WindowError, cg_and_preview, compiled_kernel,
                                           is_empty, validate_window)

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
    Port("yc", unit="m", description="lateral error at the CG as the paper defines it, yL - ls psiL"),
    Port("yc_cg", unit="m", description="the CG's signed geometric offset from the path, left positive"),
    Port("ex", unit="m/s", description="speed error vx - vx_ref"),
    Port("vx_ref", unit="m/s", description="reference speed at the CG's foot point"),
)


PLANT_NAMES: tuple[str, ...] = tuple(port.name for port in PLANT_INPUTS)
WINDOW_NAMES: tuple[str, ...] = tuple(f"ref_{name}" for name, _, _ in FIELDS)
INPUT_NAMES: tuple[str, ...] = tuple(port.name for port in CONTROLLER_INPUTS)    # plant, then ref_*
_pick_inputs = operator.itemgetter(*INPUT_NAMES)
_PI, _TWO_PI = math.pi, 2.0 * math.pi


class InputReader:
    """Checks and unpacks a controller's inputs; the window is checked and prepared once per change.

    The window only changes when the planner steps, so `read` keeps the
    PreparedWindow of the last one and reuses it while the same arrays come in
    again: the very same read-only arrays that own their data or view a read-only
    owner (the in-process master's frozen values), or arrays with the same bytes (a transport that
    decodes fresh arrays every tick). Anything else is checked and prepared anew.
    """

    def __init__(self) -> None:
        # the compiled projection's import and load now, before the first tick, not in it; or loading
        # beside the run (taken at the first read once ready)
        kernel, self._later = jit.now_or_beside(compiled_kernel)
        self._compiled = kernel is not None
        self._arrays: tuple = ()
        self._frozen = False
        self._content = b""
        self._prepared: PreparedWindow | None = None

    def read(self, inputs: Mapping[str, Value], t: float) -> tuple[tuple[float, ...], PreparedWindow | None]:
        """((x, y, psi, vx, vy, r), prepared window or None when empty); ComponentError names port, t, value.

        Args:
            inputs: the step's input mapping (PLANT_INPUTS and the ref_* window).
            t: the step's time, for messages.
        """
        return self.read_values(_pick_inputs(inputs), t, inputs)

    def read_values(self, values: tuple, t: float,
                    inputs: Mapping[str, Value] | None = None) -> tuple[tuple[float, ...], PreparedWindow | None]:
        """`read` on the inputs as a tuple in CONTROLLER_INPUTS order (a component's `step_values`).

        Args:
            values: the plant's six values, then the seven ref_* arrays;
            t: the step's time, for messages; inputs: the same as a mapping, if the caller has it
                (built from `values` only when a bad window needs it for its message).
        """
        if self._later is not None and self._later.ready:
            self._take_compiled()
        plant = tuple(map(float, values[:6]))
        if not math.isfinite(sum(plant)):
            for name, value in zip(PLANT_NAMES, plant):
                if not math.isfinite(value):
                    raise ComponentError(f"input {name!r} is not finite at t = {t}: {value}")
        arrays = values[6:]
        if self._frozen and all(map(operator.is_, arrays, self._arrays)):
            return plant, self._prepared
        try:
            content = b"".join([array.tobytes() for array in arrays])
        except AttributeError:       # not numpy arrays: the full path converts them
            content = None
        if content is None or content != self._content or not self._arrays:
            content = self._prepare(arrays, dict(zip(WINDOW_NAMES, arrays)) if inputs is None else inputs, t)
        self._arrays, self._content = arrays, content
        self._frozen = all(map(is_frozen, arrays))
        return plant, self._prepared

    def _take_compiled(self) -> None:
        """The compiled projection loaded beside the run is ready: prepare windows with it from
        this read on, the current one again (the same bits)."""
        self._compiled, self._later = self._later.kernel is not None, None
        self._arrays, self._frozen, self._content = (), False, b""

    def _prepare(self, arrays: tuple, inputs: Mapping[str, Value], t: float) -> bytes:
        """Check the window, keep its PreparedWindow (None for an all-zero window); return its bytes.

        Fast path: one (fields x points) matrix, all finite, s increasing
        (PreparedWindow.checked): the window is valid and not empty. Anything else goes through
        validate_window for a message naming the field, index and value.
        """
        try:
            matrix = np.array(arrays, dtype=np.float64)
        except (TypeError, ValueError):
            matrix = None
        if matrix is not None and matrix.ndim == 2 and matrix.shape[1] >= 2:
            self._prepared = PreparedWindow.checked(matrix, self._compiled)
            if self._prepared is not None:
                return matrix.tobytes()
        window = TrajectoryWindow.from_signals(inputs, "ref")
        self._prepared = None
        if not is_empty(window):
            try:
                validate_window(window, "ref")
            except WindowError as error:
                self._arrays, self._frozen = (), False
                raise ComponentError(f"bad trajectory window at t = {t}: {error}") from None
            self._prepared = PreparedWindow(window, self._compiled)
        return b"".join([getattr(window, name).tobytes() for name, _, _ in FIELDS])


def path_errors(w: PreparedWindow, x: float, y: float, psi: float, vx: float,
                ls: float) -> tuple[float, ...]:
    """Errors at the preview point and the reference speed at the CG's foot point.

    Args:
        w: a PreparedWindow of a valid, non-empty window (tracking slots 0 and 1).
        x, y, psi, vx: the measured CG position, yaw angle and speed.
        ls: preview distance [m].
    Returns:
        errors_at_feet's tuple.
    """
    at_cg, preview = cg_and_preview(w, x, y, psi, ls)
    return errors_at_feet(at_cg, preview, psi, vx, ls)


def errors_at_feet(at_cg: tuple, preview: tuple, psi: float, vx: float, ls: float) -> tuple[float, ...]:
    """path_errors from the feet of the CG and of the preview point (projection.foot()'s tuples).

    Plain float arithmetic, so that the backstepping step's compiled path
    (controllers.backstepping.step_jit) compiles this same source.

    Returns:
        (yL, psiL, yc, yc_cg, rho, rho_dot, vx_ref, vx_ref_dot, rho_cg, rho_cg_dot, turn,
        bend): rho and rho_dot at the preview point's foot, the reference speed and its
        rate, the curvature and its rate at the CG's foot, the path's heading change
        from the CG's foot to the preview point's and the preview foot's offset from
        the CG foot's tangent (left positive); see the module docstring.
    """
    psi_l = (psi - preview[4] + _PI) % _TWO_PI - _PI     # wrap_angle, inlined
    y_l, h_cg = preview[3], at_cg[4]
    turn = (preview[4] - h_cg + _PI) % _TWO_PI - _PI
    bend = math.cos(h_cg) * (preview[2] - at_cg[2]) - math.sin(h_cg) * (preview[1] - at_cg[1])
    return (y_l, psi_l, y_l - ls * psi_l, at_cg[3], preview[5], preview[6] * vx, at_cg[7],
            at_cg[8], at_cg[5], at_cg[6] * vx, turn, bend)


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


def finite_outputs(names: tuple[str, ...], values: tuple[float, ...], t: float) -> dict[str, float]:
    """The outputs as a dict of floats, refusing non-finite ones (ComponentError naming output, t, value).

    Args:
        names: output names; values: their float values, in the same order; t: the step's time.
    """
    if not math.isfinite(sum(values)):      # one cheap test; the loop only runs on a problem
        for name, value in zip(names, values):
            if not math.isfinite(value):
                raise ComponentError(f"at t = {t}: output {name!r} is not finite: {value}")
    return dict(zip(names, values))


def finite_values(names: tuple[str, ...], values: tuple[float, ...], t: float) -> tuple[float, ...]:
    """`values`, refusing non-finite ones as finite_outputs does (a component's `step_values`)."""
    if not math.isfinite(sum(values)):
        finite_outputs(names, values, t)
    return values


def empty_window_outputs(names: tuple[Port, ...], delta: float) -> dict[str, float]:
    """Outputs while no trajectory has arrived: hold the steer, zero torque, zero internals."""
    values = {port.name: 0.0 for port in names}
    values["delta"] = delta
    return values


__all__ = ["ActuatorLimits", "COMMAND_OUTPUTS", "CONTROLLER_INPUTS", "INPUT_NAMES", "InputReader",
           "PLANT_INPUTS", "PLANT_NAMES", "SpeedPI", "SteeringLimiter", "StepClock", "WINDOW_NAMES",
           "empty_window_outputs", "errors_at_feet", "finite_outputs", "finite_values", "path_errors"]
