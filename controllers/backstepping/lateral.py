"""Lateral two-step backstepping of the paper (eq. 9-13) as pure functions.

Error e = [yL, psiL] at the preview point, state x = [vy, r]:

    e_dot = f + g x + h rho,  f = [vx psiL, 0],  g = [[1, ls], [0, 1]],  h = [0, -vx]

Both laws share one structure. A path reference (e_r, x_r) is chosen, and with
e~ = e - e_r:

    alpha = x_r + g^-1 ( -Ke e~ - f(e~) )          (virtual control, desired x)
    z     = x - alpha
    v     = -(kz I + gz D D^T) z - (mu_hat A1 + A2) x + alpha_dot - g^T e~
    delta = B^T v / (mu_hat B^T B)                    (least-squares extraction)

- "faithful": e_r = 0 and x_r = -g^-1 h rho = [-ls vx rho, vx rho]; then alpha
  is exactly the paper's g^-1(-ke e - f - h rho) and v its eq. 12/13 right-hand
  side. B^T v is one scalar for two equations: on a constant curvature the
  residual of v orthogonal to B leaves a steady error (see steady_state tests).
- "feedforward": x_r and psiL_r are the dynamic equilibrium of the model on a
  constant curvature (r = vx rho; vy and the steady steer solve
  A x + mu_hat B delta = 0; psiL from yL_dot = 0), and yL_r is the target:
  0 with ff_target "preview", or with ff_target "cg" (default) the yL at which
  the CG lies on the path. Geometrically, with the CG on a path of curvature
  rho and heading error psiL at the preview point, the preview point's offset
  is yL = ls psiL + ls^2 rho / 2 to second order (the linear model's
  yc = yL - ls psiL ignores the path's bending between CG and preview point).
  ff_target "cg" takes each part of the equilibrium where it lives: the car's
  sideslip beta = vy / vx and yaw rate from the curvature at the CG (rho_c),
  the path's heading change `turn` and bending `bend` between the CG's foot
  and the preview point's from the window's geometry:
  psiL_r = -beta - turn, yL_r = -ls beta - bend, with the kinematic rates
  turn_dot = vx (rho_p - rho_c), bend_dot = vx (turn - ls rho_c). On a
  constant curvature (turn = ls rho, bend = ls^2 rho / 2) this is the
  equilibrium above; where the curvature changes (the preview point entering
  a bend or a lane change ahead of the CG) it is the CG-on-path state of the
  error model, whereas the constant-curvature equilibrium at rho_p asked for
  the bend's outward heading error while the CG was still on the straight:
  a steer the wrong way first (scenarios/README.md, counter-steer). At that equilibrium v lies in the span of B, so the extraction is exact and
  there is no steady error; the deviation dynamics are those of the straight
  road. psiL cannot vanish on a curve: yL_dot = 0 needs vy + vx psiL + ls r = 0.

alpha_dot is analytic: alpha depends on (e, vx, rho) only, not on x, so it
needs e_dot = f + g x + h rho from the measured x (no steering estimate is
needed), vx_dot (the nominal model with the applied torque, given by the
caller) and rho_dot = dkappa/ds vx. In the feedforward law the vx-derivative of
the (linear in rho) equilibrium is a central difference in vx; the
second derivative of e_r is neglected (it only acts while rho changes).

The adaptation law of EQUATIONS.md ("paper"), with the bracket q = v + mu_hat A1 x:

    mu_hat_dot = (g_mu / mu_hat) z^T q

"robust" (AdaptationSettings) re-derives V3_dot for the steer actually
commanded. With phi = A1 x + B delta (the tyre accelerations per unit of
friction) and r_ls = v - mu_hat B delta (the part of v no single steer can
apply: zero for a 2-input law, B-orthogonal for the least-squares one),

    z_dot = -G z - g^T e~ - r_ls + D Fwy + mu~ phi,          mu~ = mu - mu_hat
    V3_dot = -e~^T Ke e~ - z^T G z - z^T r_ls + z^T D Fwy + mu~ (z^T phi - mu_hat_dot / g_mu)

1. Regressor: mu_hat_dot = g_mu z^T phi cancels the mu~ term exactly. The
   paper's bracket is g_mu z^T (A1 x + v / mu_hat) = g_mu z^T (phi + r_ls / mu_hat):
   it also integrates z^T r_ls, which carries no information on mu. That term is
   what drives the faithful law's estimate to its floor on every curve.
2. Dead zone: with z^T G z >= kz |z|^2 + gz (D^T z)^2 and z^T D Fwy <= |D| |z| ||Fwy||,
   V3_dot <= -e~^T Ke e~ - |z| (kz |z| - |D| fwy_max - |r_ls|), so V3 decreases
   while |z| > z0 = (|D| fwy_max + |r_ls|) / kz; inside, the error is one a
   bounded side force (fwy_max) and the known residual can explain, and mu_hat
   is frozen. (The square-completion bound of EQUATIONS.md, ||Fwy||^2 / (4 gz),
   gives the radius fwy_max / (2 sqrt(kz gz)): 0.53 for kz = 20, gz = 1e5,
   fwy_max = 1500 N, ten times the 0.051 of the bound used here.)
   A side force in a steady turn and a change of grip both act along ~B
   (in a steady turn phi is ~[ay/mu, 0], 10 degrees from D at Table I): no law on this model tells
   them apart there, and the dead zone only trades one for the other. It hides
   a friction error below |D| fwy_max / |phi| (0.06 per 100 N at 1.67 m/s^2)
   and also stops the estimate's return after a gust. Measured (friction_drop,
   8-DOF): fwy_max 0 / 100 / 300 N end at mu_hat 0.496 / 0.520 / 0.548 for mu
   0.5. Hence the default 0: the dead zone covers the known residual r_ls;
   fwy_max is there for a known, persistent side-force level.
3. Excitation: adapt only while |vx r| >= a_excite (the measured centripetal
   acceleration; ay is not a controller input). On a straight road the tyres
   only balance what the model does not describe (a gust): z^T phi then
   measures the disturbance, not the grip.
4. Speed schedule: adapt only while vx >= v_adapt (the 1/vx terms of A1 and the
   path-error model's small-angle kinematics dominate near a stop).
Where it adapts, V3 decreases outside the dead zone (item 2); where it is
frozen, mu~ is constant, and the projection onto [mu_min, mu_max] (which only
removes steps leaving the interval, so it never raises V3 while mu is inside)
keeps it bounded: the (e, z) loop then sees the bounded input mu~ phi. No
leakage (sigma-modification): projection already gives the boundedness it
buys, and leakage toward mu0 biases the estimate by its prior.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cosim.component import ComponentError
from controllers.backstepping import step_kernel
from controllers.vehicle_params import VehicleParams

LATERAL_LAWS = ("faithful", "feedforward")
FF_TARGETS = ("cg", "preview")
ADAPTATIONS = ("paper", "robust")


@dataclass(frozen=True)
class AdaptationSettings:
    """Which friction adaptation law, and the robust law's thresholds (module docstring).

    Args:
        law: "paper" (EQUATIONS.md as derived) or "robust" (regressor, dead zone, excitation, speed).
        fwy_max: side force [N] the dead zone tolerates without adapting (>= 0; default 0: the
            dead zone covers the computed residual r_ls only).
        a_excite: lateral acceleration |vx r| [m/s^2] below which the estimate is frozen (>= 0).
        v_adapt: speed [m/s] below which the estimate is frozen (>= 0).
    """

    law: str = "paper"
    fwy_max: float = 0.0
    a_excite: float = 0.5
    v_adapt: float = 3.0

    def __post_init__(self) -> None:
        if self.law not in ADAPTATIONS:
            raise ComponentError(f"adaptation must be one of {ADAPTATIONS}, got {self.law!r}")
        for name in ("fwy_max", "a_excite", "v_adapt"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0.0:
                raise ComponentError(f"{name} must be a number >= 0, got {value!r}")

    def adapts(self, vx: float, r: float, z_norm: float, residual_norm: float, d_norm: float,
               kz: float) -> bool:
        """Whether the robust law integrates: speed, excitation and outside the dead zone.

        Args:
            vx, r: measured speed [m/s] and yaw rate [rad/s]; z_norm: |z|; residual_norm: |r_ls|;
            d_norm: |D|; kz: step-2 gain.
        """
        return (vx >= self.v_adapt and abs(vx * r) >= self.a_excite
                and kz * z_norm > d_norm * self.fwy_max + residual_norm)


PAPER_ADAPTATION = AdaptationSettings()


@dataclass(frozen=True)
class LateralGains:
    """Gains and settings of the lateral law.

    Args:
        ke: step-1 gains on [yL, psiL] (> 0).
        kz: step-2 gain on z (> 0).
        gz: side-wind attenuation gain (>= 0), multiplies D D^T.
        ls: preview distance [m].
        v_min: speed floor [m/s] used in place of vx below it (the law divides by vx).
        law: "faithful" or "feedforward".
        ff_target: feedforward law only: "cg" (CG on the path) or "preview" (yL = 0).
    """

    ke: tuple[float, float] = (1.0, 1.0)
    kz: float = 5.0
    gz: float = 0.0
    ls: float = 5.0
    v_min: float = 1.0
    law: str = "faithful"
    ff_target: str = "cg"

    def __post_init__(self) -> None:
        if self.law not in LATERAL_LAWS:
            raise ComponentError(f"lateral_law must be one of {LATERAL_LAWS}, got {self.law!r}")
        if self.ff_target not in FF_TARGETS:
            raise ComponentError(f"ff_target must be one of {FF_TARGETS}, got {self.ff_target!r}")
        checks = (("ke[0]", self.ke[0]), ("ke[1]", self.ke[1]), ("kz", self.kz), ("v_min", self.v_min))
        for name, value in checks:
            if not value > 0.0:
                raise ComponentError(f"{name} must be > 0, got {value!r}")
        if not self.gz >= 0.0:
            raise ComponentError(f"gz must be >= 0, got {self.gz!r}")
        if not self.ls >= 0.0:
            raise ComponentError(f"ls must be >= 0, got {self.ls!r}")


@dataclass(frozen=True)
class LateralMeasurement:
    """What the law reads: errors, body velocities, speed derivative, road curvature and its rate.

    rho, rho_dot are at the preview point's foot; rho_cg, rho_cg_dot at the
    CG's; turn is the path's heading change from the CG's foot to the preview
    point's, bend the preview foot's offset from the CG foot's tangent line
    (left positive). rho_cg None: a constant curvature rho between the two
    (turn = ls rho, bend = ls^2 rho / 2).
    """

    y_l: float
    psi_l: float
    vy: float
    r: float
    vx: float
    vx_dot: float
    rho: float
    rho_dot: float
    rho_cg: float | None = None
    rho_cg_dot: float = 0.0
    turn: float = 0.0
    bend: float = 0.0


@dataclass(frozen=True)
class LateralCommand:
    """Result of the lateral law (delta before actuator limits)."""

    delta: float
    e_tilde: np.ndarray
    alpha: np.ndarray
    z: np.ndarray
    v: np.ndarray
    mu_hat_dot: float
    V1: float
    V2: float


@dataclass(frozen=True)
class PathReference:
    """Target errors and states (and their time derivatives) the law regulates to."""

    e_r: np.ndarray
    e_r_dot: np.ndarray
    x_r: np.ndarray
    x_r_dot: np.ndarray


def steady_state_per_curvature(params: VehicleParams, vx: float, mu: float, ls: float) -> np.ndarray:
    """Model equilibrium [psiL, vy, r, delta] per unit curvature at speed vx.

    r = vx rho; vy and delta solve (mu A1 + A2) x + mu B delta = 0 (Cramer's rule);
    psiL makes yL_dot = vy + vx psiL + ls r vanish.

    Args:
        params: nominal model; vx: speed [m/s] (> 0); mu: friction used by the model; ls: preview [m].
    """
    a = params.a(vx, mu)
    b1, b2 = mu * params.b()
    r = vx
    det = a[0, 0] * b2 - a[1, 0] * b1
    if abs(det) < 1e-12 * max(abs(a[0, 0] * b2), abs(a[1, 0] * b1)):
        raise ComponentError(f"no steady-state steer at vx = {vx} m/s: model matrix is singular")
    rhs1, rhs2 = -a[0, 1] * r, -a[1, 1] * r
    vy = (rhs1 * b2 - rhs2 * b1) / det
    delta = (a[0, 0] * rhs2 - a[1, 0] * rhs1) / det
    return np.array([-(vy + ls * r) / vx, vy, r, delta])


def path_reference(m: LateralMeasurement, vx: float, params: VehicleParams, gains: LateralGains,
                   mu_hat: float) -> PathReference:
    """The (e_r, x_r) of the selected law and their time derivatives.

    Args:
        m: measurement; vx: the speed used by the law (max(vx, v_min));
        params: nominal model; gains: law settings; mu_hat: current friction estimate.
    """
    ls, rho, rho_dot, vx_dot = gains.ls, m.rho, m.rho_dot, m.vx_dot
    if gains.law == "faithful":
        kin, kin_dot = vx * rho, vx_dot * rho + vx * rho_dot
        zero = np.zeros(2)
        return PathReference(zero, zero, np.array([-ls * kin, kin]), np.array([-ls * kin_dot, kin_dot]))
    unit = steady_state_per_curvature(params, vx, mu_hat, ls)
    step = 1e-4 * vx
    unit_dvx = (steady_state_per_curvature(params, vx + step, mu_hat, ls)
                - steady_state_per_curvature(params, vx - step, mu_hat, ls)) / (2.0 * step)
    if gains.ff_target == "cg":
        return _cg_reference(m, vx, unit, unit_dvx, ls)
    unit_dot = unit * rho_dot + unit_dvx * rho * vx_dot
    return PathReference(np.array([0.0, unit[0] * rho]), np.array([0.0, unit_dot[0]]),
                         unit[1:3] * rho, unit_dot[1:3])


def _cg_reference(m: LateralMeasurement, vx: float, unit: np.ndarray, unit_dvx: np.ndarray,
                  ls: float) -> PathReference:
    """ff_target "cg": the CG on the path, curvature rho_c at the CG (module docstring)."""
    if m.rho_cg is None:
        rc, rc_dot, turn, bend = m.rho, m.rho_dot, ls * m.rho, 0.5 * ls * ls * m.rho
    else:
        rc, rc_dot, turn, bend = m.rho_cg, m.rho_cg_dot, m.turn, m.bend
    x_r = unit[1:3] * rc
    x_r_dot = unit[1:3] * rc_dot + unit_dvx[1:3] * rc * m.vx_dot
    beta, beta_dot = x_r[0] / vx, (x_r_dot[0] - x_r[0] / vx * m.vx_dot) / vx
    psi_r = -beta - turn
    psi_r_dot = -beta_dot - vx * (m.rho - rc)
    y_r = -ls * beta - bend
    y_r_dot = -ls * beta_dot - vx * (turn - ls * rc)
    return PathReference(np.array([y_r, psi_r]), np.array([y_r_dot, psi_r_dot]), x_r, x_r_dot)


def lateral_law(m: LateralMeasurement, mu_hat: float, params: VehicleParams, gains: LateralGains,
                g_mu: float = 0.0, adaptation: AdaptationSettings = PAPER_ADAPTATION) -> LateralCommand:
    """Backstepping steering command (eq. 12 with mu_hat in place of mu, i.e. eq. 13).

    Args:
        m: measured errors, states and road curvature (see LateralMeasurement).
        mu_hat: friction used by the law (the estimate, or the nominal mu when not adaptive) (> 0).
        params: the controller's nominal vehicle parameters.
        gains: gains, preview distance, speed floor and law selection.
        g_mu: adaptation gain; the returned mu_hat_dot is 0 when g_mu is 0.
        adaptation: the adaptation law ("paper" by default) and its thresholds.
    """
    vx = max(m.vx, gains.v_min)
    ls = gains.ls
    ke = np.array(gains.ke, dtype=float)
    g_inv = np.array([[1.0, -ls], [0.0, 1.0]])
    g_t = np.array([[1.0, 0.0], [ls, 1.0]])
    ref = path_reference(m, vx, params, gains, mu_hat)
    e = np.array([m.y_l, m.psi_l])
    x = np.array([m.vy, m.r])
    e_t = e - ref.e_r
    e_dot = np.array([vx * m.psi_l + m.vy + ls * m.r, m.r - vx * m.rho])
    e_t_dot = e_dot - ref.e_r_dot
    alpha = ref.x_r + g_inv @ (-ke * e_t - np.array([vx * e_t[1], 0.0]))
    f_t_dot = np.array([m.vx_dot * e_t[1] + vx * e_t_dot[1], 0.0])
    alpha_dot = ref.x_r_dot + g_inv @ (-ke * e_t_dot - f_t_dot)
    z = x - alpha
    d = params.d()
    gain_z = gains.kz * np.eye(2) + gains.gz * np.outer(d, d)
    a1 = params.a1(vx)
    v = -gain_z @ z - (mu_hat * a1 + params.a2(vx)) @ x + alpha_dot - g_t @ e_t
    b = params.b()
    delta = float(b @ v) / (mu_hat * float(b @ b))
    if adaptation.law == "paper":
        mu_hat_dot = (g_mu / mu_hat) * float(z @ (v + mu_hat * (a1 @ x)))
    else:
        phi = a1 @ x + b * delta
        residual = v - mu_hat * b * delta
        active = adaptation.adapts(m.vx, m.r, float(np.linalg.norm(z)), float(np.linalg.norm(residual)),
                                   float(np.linalg.norm(d)), gains.kz)
        mu_hat_dot = g_mu * float(z @ phi) if active else 0.0
    v1 = 0.5 * float(e_t @ e_t)
    return LateralCommand(delta=delta, e_tilde=e_t, alpha=alpha, z=z, v=v, mu_hat_dot=mu_hat_dot,
                          V1=v1, V2=v1 + 0.5 * float(z @ z))


class ScalarLateralLaw:
    """lateral_law in scalar arithmetic with constants precomputed: the controller's per-tick form.

    Same equations as lateral_law and path_reference (the numpy forms, kept as
    the readable reference; a test holds the two together), written out for
    the 2x2 matrices and 2-vectors in controllers.backstepping.step_kernel,
    with everything that depends only on the parameters and gains computed
    once, here, into `constants` (step_kernel's lateral indices).

    Args:
        params: the controller's nominal vehicle parameters; gains: gains and law selection;
        adaptation: the friction adaptation law and its thresholds.
    """

    def __init__(self, params: VehicleParams, gains: LateralGains,
                 adaptation: AdaptationSettings = PAPER_ADAPTATION) -> None:
        m, iz, cf, cr, lf, lr = params.m, params.Iz, params.Cf, params.Cr, params.lf, params.lr
        self.gains, self.adaptation = gains, adaptation
        self.robust = adaptation.law == "robust"
        self.ls = gains.ls
        c00, c01 = -2.0 * (cf + cr) / m, 2.0 * (cr * lr - cf * lf) / m
        c10, c11 = 2.0 * (cr * lr - cf * lf) / iz, -2.0 * (cf * lf**2 + cr * lr**2) / iz
        self.b0, self.b1 = 2.0 * cf / m, 2.0 * cf * lf / iz
        d0, d1 = 1.0 / m, params.lw / iz
        self.d_norm = math.hypot(d0, d1)
        g00, g01 = gains.kz + gains.gz * d0 * d0, gains.gz * d0 * d1
        g11 = gains.kz + gains.gz * d1 * d1
        flags = (float(gains.law == "feedforward"), float(gains.ff_target == "cg"), float(self.robust))
        self.constants: tuple[float, ...] = (
            c00, c01, c10, c11, self.b0, self.b1, self.b0 * self.b0 + self.b1 * self.b1, g00, g01, g11,
            gains.ls, *gains.ke, gains.v_min, *flags)
        assert len(self.constants) == step_kernel.LATERAL_SIZE

    def command(self, y_l: float, psi_l: float, vy: float, r: float, vx: float, vx_dot: float,
                rho: float, rho_dot: float, mu_hat: float, g_mu: float, rho_cg: float | None = None,
                rho_cg_dot: float = 0.0, turn: float = 0.0, bend: float = 0.0) -> tuple[float, ...]:
        """lateral_law as (delta, alpha_vy, alpha_r, z_vy, z_r, mu_hat_dot, V2).

        Args: as LateralMeasurement's fields (vx measured, floored in the law), with mu_hat
        and g_mu after rho_dot.
        """
        if rho_cg is None:
            ls = self.ls
            rho_cg, rho_cg_dot, turn, bend = rho, rho_dot, ls * rho, 0.5 * ls * ls * rho
        try:
            delta, alpha0, alpha1, z0, z1, mu_hat_dot, v2, v0, v1, a1x0, a1x1 = step_kernel.lateral_command(
                self.constants, y_l, psi_l, vy, r, vx, vx_dot, rho, rho_dot, mu_hat, g_mu, rho_cg,
                rho_cg_dot, turn, bend)
        except step_kernel.SingularSteer as singular:
            raise singular_steer_error(singular) from None
        if self.robust:
            mu_hat_dot = self.robust_rate(vx, r, z0, z1, v0, v1, a1x0, a1x1, delta, mu_hat, g_mu)
        return delta, alpha0, alpha1, z0, z1, mu_hat_dot, v2

    def robust_rate(self, vx: float, r: float, z0: float, z1: float, v0: float, v1: float,
                    a1x0: float, a1x1: float, delta: float, mu_hat: float, g_mu: float) -> float:
        """The robust law's mu_hat_dot: g_mu z^T (A1 x + B delta) when AdaptationSettings.adapts.

        vx is the measured speed (not floored); the others as step_kernel.lateral_command gives them.
        """
        bd0, bd1 = self.b0 * delta, self.b1 * delta
        residual = math.hypot(v0 - mu_hat * bd0, v1 - mu_hat * bd1)
        if not self.adaptation.adapts(vx, r, math.hypot(z0, z1), residual, self.d_norm, self.gains.kz):
            return 0.0
        return g_mu * (z0 * (a1x0 + bd0) + z1 * (a1x1 + bd1))


def singular_steer_error(singular: step_kernel.SingularSteer) -> ComponentError:
    """The ComponentError of a SingularSteer (the feedforward law's model has no steady steer)."""
    return ComponentError(f"no steady-state steer at vx = {singular.args[0]} m/s: model matrix is singular")


def project_mu(mu_hat: float, mu_min: float, mu_max: float) -> float:
    """Projection of the friction estimate onto [mu_min, mu_max].

    Args:
        mu_hat: the estimate after an integration step; mu_min, mu_max: bounds (0 < mu_min <= mu_max).
    """
    return min(mu_max, max(mu_min, mu_hat))
