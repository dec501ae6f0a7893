"""The scenario parameters of the trajectory `Planner`: names, types, units, defaults, ranges.

The model is the planner's `parameters_model`; its fields are the constructor's
keyword arguments with the same defaults (a test holds them equal). The road
and the manoeuvre are nested specs that the planner's own readers check
(controllers.road.builders.road_from_spec, controllers.planning.manoeuvres):
here they are a builder name or a mapping. The speed limits are typed, their
defaults those of SpeedLimits.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field

from controllers.parameter_fields import PARAMETERS_CONFIG
from controllers.planning.speed_profile import V_LIMIT, SpeedLimits
from controllers.road.builders import BUILDERS
from controllers.spec import MAX_LENGTH, MAX_REACH

RoadBuilder = Literal[tuple(BUILDERS)]  # type: ignore[valid-type]


class SpeedSpec(BaseModel):
    """Comfort limits of the reference speed (controllers.planning.speed_profile.SpeedLimits)."""

    model_config = PARAMETERS_CONFIG
    v_max: float = Field(SpeedLimits.v_max, gt=0, lt=V_LIMIT,
                         description="top speed, m/s (below 50 km/h)")
    a_lat_max: float = Field(SpeedLimits.a_lat_max, gt=0,
                             description="lateral acceleration bound in curves, v^2 |kappa|, m/s^2")
    a_max: float = Field(SpeedLimits.a_max, gt=0, description="longitudinal acceleration "
                                                              "bound, m/s^2")
    d_max: float = Field(SpeedLimits.d_max, gt=0, description="longitudinal deceleration "
                                                              "bound (a positive number), m/s^2")
    j_max: float = Field(SpeedLimits.j_max, gt=0, description="longitudinal jerk bound, m/s^3")


class PlannerParameters(BaseModel):
    """Parameters of controllers.planning:Planner (road, manoeuvre, speed profile, windows)."""

    model_config = PARAMETERS_CONFIG
    road: RoadBuilder | dict[str, Any] = Field(
        "satory_standin", description="the road: a builder name, {builder: name, ...its "
                                      "arguments}, {reference: {segments: [...]}, lanes, "
                                      "lane_width} or {opendrive: file, road, lane}")
    lane: int = Field(0, ge=0, description="starting lane, 0 = the reference line, 1")
    manoeuvre: dict[str, Any] | None = Field(
        None, description="the manoeuvre, {type: lane_keeping | lane_change | "
                          "obstacle_avoidance | vehicle_following, ...} (null: keep the lane)")
    speed: SpeedSpec | None = Field(None, description="speed limits of the reference profile "
                                                      "(null: every default)")
    start_from_rest: bool | None = Field(None, description="start the speed profile at v = 0 "
                                                           "(null: if vx < 0.1 m/s at t0)")
    stop_at_end: bool = Field(True, description="stop at the end of the route")
    laps: int = Field(1, ge=1, description="laps of a closed road, 1")
    distance: float | None = Field(None, gt=0, le=MAX_LENGTH, description=(
        "route length on an open road, m (null: to its end)"))
    window_spacing: float = Field(0.5, gt=0, le=MAX_REACH, description=(
        "minimum spacing of the window points, m"))
    window_back: float = Field(3.0, gt=0, le=MAX_REACH, description=(
        "how far behind the vehicle the window starts, m"))
    preview: float = Field(5.0, gt=0, le=MAX_REACH, description=(
        "the controller's look-ahead distance the window must cover, m"))
    planner_period: float = Field(0.1, gt=0, le=60.0, description=(
        "this component's period, for the window coverage, s"))
    launch_offset: float = Field(2.0, gt=0, le=MAX_REACH, description=(
        "from rest, how far behind the vehicle the profile's v = 0 point lies, m"))
    obstacle_range: float = Field(1000.0, gt=0, description="cap of the output "
                                                            "obstacle_distance, m")
    off_road: float = Field(20.0, gt=0, description="the run stops when the vehicle is this "
                                                    "far outside the road's edges, m")
