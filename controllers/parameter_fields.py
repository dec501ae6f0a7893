"""Typed fields shared by the parameter models of the controller components.

Each shipped component class declares a pydantic model of its constructor's
keyword arguments (`parameters_model`, see cosim.component.Component): the
scenario loader validates a scenario's `parameters:` with it and the scenario
JSON schema describes them, so an editor completes and checks them. The
fields the controllers share (the nominal vehicle, the actuator limits, the
PI speed loop) are defined once here, with unit, range and meaning; each
model gives them its defaults, which a test holds equal to the constructor's.
Ranges are the constructors' own single-field checks; checks that relate two
fields (mu_min <= mu0 <= mu_max, min_torque < max_torque) stay in the constructors.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import ConfigDict, Field

#: unknown names refused; a bool or a string is never read as a number; no inf or nan
PARAMETERS_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

# the controller's nominal vehicle model (Table I of the paper; controllers.vehicle_params)
Mass = Annotated[float, Field(gt=0, description="nominal vehicle mass, kg")]
YawInertia = Annotated[float, Field(gt=0, description="nominal yaw inertia, kg m^2")]
Cornering = Annotated[float, Field(gt=0, description="nominal cornering stiffness per tyre, N/rad")]
FrontArm = Annotated[float, Field(gt=0, description="CG to front axle distance, m")]
RearArm = Annotated[float, Field(gt=0, description="CG to rear axle distance, m")]
WheelInertia = Annotated[float, Field(gt=0, description="equivalent wheel spin inertia, kg m^2")]
WheelRadius = Annotated[float, Field(gt=0, description="wheel radius, m")]
WindArm = Annotated[float, Field(description="lever arm of the side-wind force ahead of the CG, m "
                                             "(0 or negative allowed)")]

# actuator limits (controllers.tracking.ActuatorLimits) and the first step
MaxDelta = Annotated[float, Field(gt=0, description="steering angle bound, rad")]
MaxDeltaRate = Annotated[float, Field(gt=0, description="steering rate bound, rad/s")]
MaxTorque = Annotated[float, Field(description="largest drive torque, N.m (above min_torque)")]
MinTorque = Annotated[float, Field(description="most negative (braking) torque, N.m "
                                               "(below max_torque)")]
FirstPeriod = Annotated[float, Field(gt=0, description="time step assumed at the first step "
                                                       "(later steps measure it), s")]
Preview = Annotated[float, Field(ge=0, description="preview distance ahead of the CG where yL "
                                                   "and psiL are measured, m")]

# the PI speed loop of the baselines (controllers.tracking.SpeedPI)
SpeedKp = Annotated[float, Field(gt=0, description="proportional speed gain, N/(m/s)")]
SpeedKi = Annotated[float, Field(ge=0, description="integral speed gain, N/m")]
