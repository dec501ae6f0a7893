"""The scenario parameters of `BacksteppingController`: names, types, units, defaults, ranges.

The model is the controller's `parameters_model`; its fields are the
constructor's keyword arguments with the same defaults (a test holds them equal).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from controllers.parameter_fields import (PARAMETERS_CONFIG, Cornering, FirstPeriod, FrontArm,
                                          Mass, MaxDelta, MaxDeltaRate, MaxTorque, MinTorque,
                                          Preview, RearArm, WheelInertia, WheelRadius, WindArm,
                                          YawInertia)

PositiveGain = Annotated[float, Field(gt=0)]


class BacksteppingParameters(BaseModel):
    """Parameters of controllers.backstepping:BacksteppingController (the paper's law)."""

    model_config = PARAMETERS_CONFIG
    m: Mass = 1500.0
    Iz: YawInertia = 2454.0
    Cf: Cornering = 57500.0
    Cr: Cornering = 57500.0
    lf: FrontArm = 1.006
    lr: RearArm = 1.462
    iy: WheelInertia = 1.2
    Rw: WheelRadius = 0.3
    lw: WindArm = 0.3
    ls: Preview = 5.0
    kx: float = Field(1500.0, gt=0, description="longitudinal gain on the speed error, kg/s")
    gx: float = Field(1500.0, gt=0, description="longitudinal disturbance gain, kg/s")
    ke: PositiveGain | Annotated[list[PositiveGain], Field(min_length=2, max_length=2)] = Field(
        1.0, description="step-1 gain on [yL, psiL], 1/s: one number for both or a list of two")
    kz: float = Field(5.0, gt=0, description="step-2 gain on the backstepping error z, 1/s")
    gz: float = Field(1.0e5, ge=0, description="side-wind attenuation gain, multiplies D D^T "
                                                "(D = [1/m, lw/Iz]), kg^2/s")
    g_mu: float = Field(0.5, ge=0, description="friction adaptation gain of mu_hat_dot = "
                                                "g_mu z^T phi, s^2/m^2 (read when adaptive)")
    mu0: float = Field(1.0, gt=0, description="initial (or, not adaptive, fixed) friction "
                                              "coefficient, 1; mu_min <= mu0 <= mu_max")
    mu_min: float = Field(0.1, gt=0, description="lower bound of the friction estimate, 1")
    mu_max: float = Field(1.2, gt=0, description="upper bound of the friction estimate, 1")
    adaptive: bool = Field(False, description="estimate the friction online (eq. 13) instead "
                                              "of using mu0 (eq. 12)")
    adaptation: Literal["paper", "robust"] = Field(
        "paper", description="adaptation law: 'paper' (EQUATIONS.md) or 'robust' (applied-steer "
                             "regressor, dead zone, excitation and speed conditions)")
    fwy_max: float = Field(0.0, ge=0, description="robust law: side force the dead zone "
                                                  "tolerates without adapting, N")
    a_excite: float = Field(0.5, ge=0, description="robust law: mu_hat frozen while |vx r| is "
                                                   "below this, m/s^2")
    v_adapt: float = Field(3.0, ge=0, description="robust law: mu_hat frozen below this "
                                                  "speed, m/s")
    lateral_law: Literal["faithful", "feedforward"] = Field(
        "faithful", description="lateral law: 'faithful' (the paper's) or 'feedforward' "
                                "(no steady error on curves)")
    ff_target: Literal["cg", "preview"] = Field(
        "cg", description="what the feedforward law zeroes: 'cg' (CG on the path) or "
                          "'preview' (yL)")
    max_delta: MaxDelta = 0.5
    max_delta_rate: MaxDeltaRate = 1.0
    max_torque: MaxTorque = 3000.0
    min_torque: MinTorque = -6000.0
    v_min: float = Field(1.0, gt=0, description="speed floor of the lateral law (it divides "
                                                "by vx), m/s")
    period: FirstPeriod = 0.01
    mu_true: float = Field(1.0, description="true friction coefficient, 1: only for the "
                                            "diagnostic output V3")
