"""Longitudinal backstepping speed law of the paper (eq. 7), as pure functions.

With ex = vx - vx_ref and V = me ex^2 / 2, the equivalent-wheel model
me vx_dot = tau_w / Rw + m vy r + Fwx and the law

    tau_w = Rw ( -(kx + gx) ex - m vy r + me vx_ref_dot )

give V_dot = -(kx + gx) ex^2 + ex Fwx <= -kx ex^2 + Fwx^2 / (4 gx), hence
|ex| <= max(|ex(0)|, ||Fwx||_inf / (2 sqrt(gx kx))). Aerodynamic drag is part
of Fwx and is not compensated (as in the paper).
"""

from __future__ import annotations

from dataclasses import dataclass

from controllers.vehicle_params import VehicleParams


@dataclass(frozen=True)
class LongitudinalCommand:
    """Result of the speed law: torque before saturation, speed error and V = me ex^2 / 2."""

    torque: float
    ex: float
    V: float


def longitudinal_law(vx: float, vx_ref: float, vx_ref_dot: float, vy: float, r: float,
                     params: VehicleParams, kx: float, gx: float) -> LongitudinalCommand:
    """Eq. 7: total wheel torque tracking the reference speed.

    Args:
        vx, vy, r: measured body velocities [m/s] and yaw rate [rad/s].
        vx_ref, vx_ref_dot: reference speed [m/s] and acceleration [m/s2].
        params: the controller's nominal vehicle parameters.
        kx, gx: the law's gains [kg/s] (> 0); gx sets the disturbance attenuation.
    """
    ex = vx - vx_ref
    torque = params.Rw * (-(kx + gx) * ex - params.m * vy * r + params.me * vx_ref_dot)
    return LongitudinalCommand(torque=torque, ex=ex, V=0.5 * params.me * ex * ex)


def speed_error_bound(ex0: float, fwx_max: float, kx: float, gx: float) -> float:
    """The bound max(|ex(0)|, ||Fwx||_inf / (2 sqrt(gx kx))) of EQUATIONS.md on |ex(t)|.

    Args:
        ex0: initial speed error [m/s]; fwx_max: bound on |Fwx| [N]; kx, gx: gains.
    """
    return max(abs(ex0), fwx_max / (2.0 * (gx * kx) ** 0.5))


def nominal_vx_dot(torque: float, vy: float, r: float, params: VehicleParams) -> float:
    """Acceleration the nominal model predicts for an applied torque, without disturbance.

    Args:
        torque: applied total wheel torque [N.m]; vy, r: body lateral speed and yaw rate.
        params: nominal vehicle parameters.
    """
    return (torque / params.Rw + params.m * vy * r) / params.me
