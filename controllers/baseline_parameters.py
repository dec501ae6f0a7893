"""The scenario parameters of the baseline controllers (controllers.baselines): names,
types, units, defaults, ranges.

Each model is its class's `parameters_model`; its fields are the constructor's
keyword arguments with the same defaults (a test holds them equal).
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from controllers.parameter_fields import (PARAMETERS_CONFIG, FirstPeriod, FrontArm, Mass,
                                          MaxDelta, MaxDeltaRate, MaxTorque, MinTorque, Preview,
                                          RearArm, SpeedKi, SpeedKp, WheelInertia, WheelRadius)


class _Wheels(BaseModel):
    """The nominal vehicle of the speed loop's feed-forward."""

    model_config = PARAMETERS_CONFIG
    m: Mass = 1500.0
    iy: WheelInertia = 1.2
    Rw: WheelRadius = 0.3


class _SpeedLoop(BaseModel):
    """The PI speed loop on torque, its limits and the first step."""

    model_config = PARAMETERS_CONFIG
    kp: SpeedKp = 3000.0
    ki: SpeedKi = 600.0
    max_torque: MaxTorque = 3000.0
    min_torque: MinTorque = -6000.0
    period: FirstPeriod = 0.01


class SpeedLoopParameters(_SpeedLoop, _Wheels):
    """Parameters of controllers.baselines:SpeedLoop (PI on torque for a scripted speed)."""


class _Tracking(_Wheels):
    """The geometry both path-tracking baselines take, and their steering limits."""

    lf: FrontArm = 1.006
    lr: RearArm = 1.462
    ls: Preview = 5.0
    max_delta: MaxDelta = 0.5
    max_delta_rate: MaxDeltaRate = 1.0


class PurePursuitParameters(_SpeedLoop, _Tracking):
    """Parameters of controllers.baselines:PurePursuitController."""

    ld_min: float = Field(4.0, gt=0, description="smallest look-ahead distance, m")
    ld_gain: float = Field(0.6, ge=0, description="look-ahead distance per unit speed, s")


class StanleyParameters(_SpeedLoop, _Tracking):
    """Parameters of controllers.baselines:StanleyController."""

    k_stanley: float = Field(1.0, gt=0, description="cross-track gain, 1/s")
    k_soft: float = Field(1.0, gt=0, description="speed softening of the cross-track term, m/s")
