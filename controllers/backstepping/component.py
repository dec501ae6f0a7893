"""The paper's combined longitudinal-lateral backstepping controller as a component.

`BacksteppingController` wraps the laws of backstepping_longitudinal (eq. 7)
and backstepping_lateral (eq. 9-13, faithful or feedforward variant), with the
optional adaptive friction estimate, the actuator limits and the window
projection. The step runs every tick, so it uses the scalar forms: the window
checked and prepared once per new window (controllers.tracking.InputReader),
the projection, then everything else in controllers.backstepping.step_kernel
(eq. 7, the lateral law, the limits), which numba compiles from the same
source when it is installed (COSIM_JIT; step_path chooses); tests hold both
to the readable numpy forms. With both the projection and the step compiled, the
projection writes the feet into a buffer that the compiled step reads, and only
the tangents' math.hypot runs in between (CPython's, for the interpreted path's bits). Each step:

1. dt from consecutive step times (first step: `period`);
2. friction estimate: explicit Euler with the previous step's mu_hat_dot, then
   projection onto [mu_min, mu_max];
3. errors at the preview point and the reference speed (control_common);
4. torque from eq. 7, clipped; vx_dot predicted by the nominal model with the
   applied torque (for alpha_dot);
5. steering from the lateral law with mu_hat (adaptive) or mu0, then the angle
   and rate limits.

Adaptation: `adaptation` "paper" is EQUATIONS.md's law; "robust" (derived in
backstepping_lateral's docstring) uses the regressor of the steer actually
commanded and adapts only outside a dead zone, while excited and above v_adapt.
Anti-windup (both): mu_hat is frozen for the next step when the steering command was
limited (the law's assumption that mu B delta acts fully is then false), and
below v_min. Low speed: below v_min the lateral law uses v_min in place of vx
(it divides by vx); steering stays continuous and bounded.
Measured caveat: with the faithful law the least-squares residual keeps z
non-zero on a curve, so the adaptation law drifts even when mu_hat = mu (on
R = 50 m at 10 m/s, mu = 1, mu_hat0 = 1: 0.49 after 10 s, then mu_min). With
lateral_law "feedforward" z vanishes at equilibrium and the estimate moves to
the true friction (0.4 -> 0.96 and 1.0 -> 0.60 for mu = 1.0 / 0.6 in 10 s).
adaptation "robust" removes that drift (and the drift under a side force on a
straight road or near a stop); tests/controllers/backstepping/test_adaptation.py compares.
No trajectory yet (an all-zero window): steering held, torque 0, internals 0.
V3 uses `mu_true`, a diagnostic parameter the control law never reads.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping, Sequence
from math import hypot

import numpy as np

from cosim.component import Component, ComponentError, ModelReference, Port, Value
from controllers import jit
from controllers.backstepping import step_kernel
from controllers.backstepping.lateral import (AdaptationSettings, LateralGains, ScalarLateralLaw,
                                              singular_steer_error)
from controllers.backstepping.step_path import compiled_step
from controllers.road.projection import FEET_SIZE, cg_and_preview
from controllers.tracking import (COMMAND_OUTPUTS, CONTROLLER_INPUTS, INPUT_NAMES, ActuatorLimits, InputReader,
                                  SteeringLimiter, StepClock, empty_window_outputs, finite_values)
from controllers.vehicle_params import VehicleParams

BACKSTEPPING_OUTPUTS: tuple[Port, ...] = COMMAND_OUTPUTS + (
    Port("rho", unit="1/m", description="road curvature at the preview point"),
    Port("mu_hat", unit="1", description="friction estimate used by the law (mu0 if not adaptive)"),
    Port("alpha_vy", unit="m/s", description="virtual control, lateral speed"),
    Port("alpha_r", unit="rad/s", description="virtual control, yaw rate"),
    Port("z_vy", unit="m/s", description="backstepping error vy - alpha_vy"),
    Port("z_r", unit="rad/s", description="backstepping error r - alpha_r"),
    Port("V", unit="J", description="longitudinal Lyapunov function me ex^2 / 2"),
    Port("V2", unit="1", description="lateral Lyapunov function (e^T e + z^T z) / 2"),
    Port("V3", unit="1", description="V2 + (mu_true - mu_hat)^2 / (2 g_mu) (diagnostic)"),
)
OUTPUT_NAMES: tuple[str, ...] = tuple(port.name for port in BACKSTEPPING_OUTPUTS)
_pick_inputs = operator.itemgetter(*INPUT_NAMES)


def _gain_pair(name: str, value: float | Sequence[float]) -> tuple[float, float]:
    """A scalar or 2-vector gain as a pair of floats."""
    if isinstance(value, (int, float)):
        return float(value), float(value)
    items = [float(item) for item in value]
    if len(items) != 2:
        raise ComponentError(f"{name} must be a number or a list of 2 numbers, got {value!r}")
    return items[0], items[1]


class BacksteppingController(Component):
    """Backstepping path and speed tracking (see module docstring).

    Args:
        m, Iz, Cf, Cr, lf, lr, iy, Rw, lw: the controller's nominal model (Table I defaults).
        ls: preview distance [m].
        kx, gx: longitudinal gains [kg/s].
        ke: step-1 gain, scalar or [k_yL, k_psiL]; kz: step-2 gain; gz: side-wind gain.
        g_mu: adaptation gain; mu0: initial (or fixed) friction; mu_min, mu_max: projection bounds.
        adaptive: estimate mu online (eq. 13) instead of using mu0 (eq. 12).
        adaptation: "paper" (the adaptation law of EQUATIONS.md, the faithful reference) or
            "robust" (backstepping_lateral's docstring: applied-steer regressor, dead zone,
            excitation and speed conditions); only read when adaptive.
        fwy_max: robust law's dead zone: side force [N] it tolerates without adapting.
        a_excite: robust law: freeze mu_hat while |vx r| is below this [m/s^2].
        v_adapt: robust law: freeze mu_hat below this speed [m/s].
        lateral_law: "faithful" (the paper's) or "feedforward" (no steady error on curves).
        ff_target: what the feedforward law zeroes: "cg" (CG on the path) or "preview" (yL).
        max_delta, max_delta_rate, max_torque, min_torque: actuator limits.
        v_min: speed floor of the lateral law [m/s]; period: first step's dt [s].
        mu_true: true friction, only for the diagnostic output V3.
    """

    inputs = CONTROLLER_INPUTS
    outputs = BACKSTEPPING_OUTPUTS
    default_period = 0.01
    parameters_model = ModelReference("controllers.backstepping.parameters:BacksteppingParameters")

    def __init__(self, *, m: float = 1500.0, Iz: float = 2454.0, Cf: float = 57500.0,
                 Cr: float = 57500.0, lf: float = 1.006, lr: float = 1.462, iy: float = 1.2,
                 Rw: float = 0.3, lw: float = 0.3, ls: float = 5.0, kx: float = 1500.0,
                 gx: float = 1500.0, ke: float | Sequence[float] = 1.0, kz: float = 5.0,
                 gz: float = 1.0e5, g_mu: float = 0.5, mu0: float = 1.0, mu_min: float = 0.1,
                 mu_max: float = 1.2, adaptive: bool = False, adaptation: str = "paper",
                 fwy_max: float = 0.0, a_excite: float = 0.5, v_adapt: float = 3.0,
                 lateral_law: str = "faithful",
                 ff_target: str = "cg",
                 max_delta: float = 0.5, max_delta_rate: float = 1.0, max_torque: float = 3000.0,
                 min_torque: float = -6000.0, v_min: float = 1.0, period: float = 0.01,
                 mu_true: float = 1.0) -> None:
        self.params = VehicleParams(m=m, Iz=Iz, Cf=Cf, Cr=Cr, lf=lf, lr=lr, iy=iy, Rw=Rw, lw=lw)
        self.gains = LateralGains(ke=_gain_pair("ke", ke), kz=kz, gz=gz, ls=ls, v_min=v_min,
                                  law=lateral_law, ff_target=ff_target)
        if not (kx > 0.0 and gx > 0.0):
            raise ComponentError(f"kx and gx must be > 0, got kx={kx!r}, gx={gx!r}")
        if not 0.0 < mu_min <= mu0 <= mu_max:
            raise ComponentError(f"need 0 < mu_min <= mu0 <= mu_max, got {mu_min!r}, {mu0!r}, {mu_max!r}")
        if not g_mu >= 0.0:
            raise ComponentError(f"g_mu must be >= 0, got {g_mu!r}")
        self.kx, self.gx = float(kx), float(gx)
        self.g_mu = float(g_mu) if adaptive else 0.0
        self.mu_min, self.mu_max, self.mu_true = float(mu_min), float(mu_max), float(mu_true)
        self.limits = ActuatorLimits(max_delta, max_delta_rate, max_torque, min_torque)
        self.steering = SteeringLimiter(self.limits)
        self.clock = StepClock(period)
        self.mu_hat = float(mu0)
        self.mu_hat_dot = 0.0
        self.reader = InputReader()
        self.adaptation = AdaptationSettings(law=adaptation, fwy_max=fwy_max, a_excite=a_excite,
                                             v_adapt=v_adapt)
        self.lateral = ScalarLateralLaw(self.params, self.gains, self.adaptation)
        constants = self.lateral.constants + (
            self.params.m, self.params.me, self.params.Rw, self.kx + self.gx, self.limits.max_torque,
            self.limits.min_torque, self.limits.max_delta, self.limits.max_delta_rate, self.mu_min,
            self.mu_max, self.g_mu)
        assert len(constants) == step_kernel.STEP_SIZE
        self._step_constants = constants
        # the compiled step now, or loading beside the run (taken between two steps once ready)
        compiled, self._later = jit.now_or_beside(compiled_step)
        self._use_step(compiled)
        self._feet, self._ls = np.zeros(FEET_SIZE), float(ls)     # a float: the compiled code's one signature

    def _use_step(self, compiled) -> None:
        """Step with controllers.backstepping.step_jit `compiled`, or interpreted when it is None."""
        self._step, self._constants = ((compiled.step, compiled.constants(self._step_constants))
                                       if compiled is not None else (step_kernel.step, self._step_constants))
        # the projection and the step both compiled: the step takes the feet from the projection's buffer
        self._step_on_feet = compiled.step_on_feet if compiled is not None else None

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """One control step at time t (see module docstring): step_values on the mapping."""
        return dict(zip(OUTPUT_NAMES, self.step_values(t, _pick_inputs(inputs))))

    def step_values(self, t: float, values: tuple) -> tuple[float, ...]:
        """`step` on the inputs in CONTROLLER_INPUTS order; the outputs in OUTPUT_NAMES order."""
        if self._later is not None and self._later.ready:   # the same bits from here on, compiled
            self._use_step(self._later.kernel)
            self._later = None
        dt = self.clock.advance(t)
        (x, y, psi, vx, vy, r), window = self.reader.read_values(values, t)
        if window is None:
            return self._empty_window
        try:
            if window.compiled_feet is not None and self._step_on_feet is not None:
                feet = self._feet
                dx_cg, dy_cg, dx_preview, dy_preview = window.compiled_feet(x, y, psi, self._ls, feet)
                result = self._step_on_feet(self._constants, feet, hypot(dx_cg, dy_cg), hypot(dx_preview, dy_preview),
                                            x, y, dt, self.mu_hat, self.mu_hat_dot, self.steering.last,
                                            psi, vx, vy, r)
            else:
                at_cg, preview = cg_and_preview(window, x, y, psi, self.gains.ls)
                result = self._step(self._constants, dt, self.mu_hat, self.mu_hat_dot, self.steering.last,
                                    psi, vx, vy, r, at_cg, preview)
        except step_kernel.SingularSteer as singular:
            raise singular_steer_error(singular) from None
        # result: the outputs up to V2, then command, mu_hat_dot, kept, v0, v1, a1x0, a1x1
        self.steering.last, mu_hat = result[0], result[9]
        self.mu_hat = mu_hat
        rate = result[17]
        if result[18] == 0.0:       # the steer was limited, or vx < v_min: mu_hat is frozen
            rate = 0.0
        elif self.lateral.robust:
            rate = self.lateral.robust_rate(vx, r, result[12], result[13], *result[19:], result[16], mu_hat,
                                            self.g_mu)
        self.mu_hat_dot = rate
        v3 = result[15] + ((self.mu_true - mu_hat) ** 2 / (2.0 * self.g_mu) if self.g_mu > 0.0 else 0.0)
        return finite_values(OUTPUT_NAMES, result[:16] + (v3,), t)

    @property
    def _empty_window(self) -> tuple[float, ...]:
        """The outputs while no trajectory has arrived (empty_window_outputs, with mu_hat held)."""
        held = empty_window_outputs(self.outputs, self.steering.last) | {"mu_hat": self.mu_hat}
        return tuple(held[name] for name in OUTPUT_NAMES)
