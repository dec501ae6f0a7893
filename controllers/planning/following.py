"""Vehicle following: a constant-time-gap policy turns the gap to a lead vehicle into the speed reference.

The planner's fourth manoeuvre (`manoeuvre: {type: vehicle_following, ...}`):
the follower keeps its lane (the lane_keeping options) and its speed is set
by the lead vehicle ahead in the same lane, whose position and speed reach
the planner on the inputs lead_x, lead_y and lead_vx.

Gap g: the lead's progress along the road's reference line minus the
follower's, minus `vehicle_length` (the manoeuvre's Comfort field, 4.5 m;
both cars that long, CG at the centre), so bumper to bumper, measured along
the road (on a bend, not the chord). On a closed road the lead's progress is
taken within half a lap of the follower's.

Policy, at each planner step (dt = time since the previous one), with v the
follower's measured speed and v_lead the lead's:

    g*    = standstill + time_gap * v                   desired gap
    a_des = k_gap (g - g*) + k_speed (v_lead - v)       gap and speed feedback
    a_des = min(a_des, a_road + (v_road - v_ref) / T_ROAD)    never above the road's profile
    a_des = clip(a_des, -d_max, a_max)
    a_des = max(a_des, a_land)   soft landing: a^2 <= 2 j_max v_ref after the step, so that braking
                                 can fade out at j_max as v_ref reaches 0 (binds below about
                                 v_ref = d_max^2 / (2 j_max); TimeGapSpeed._landing)
    a     = a + clip(a_des - a, -j_max dt, j_max dt)    jerk limit
    v_ref = max(v_ref + (a_prev + a) dt / 2, 0)         the speed reference (trapezoid)

A lead farther than `range` (or behind the follower) leaves the follower on
the road's speed profile (v_road, a_road: the lane_keeping profile at the
vehicle, limited by `speed:` and curvature). With a lead at constant speed V
the only equilibrium is v = V, g = standstill + time_gap * V: the
constant-time-gap steady state. The acceleration reference a is always within
[-d_max, a_max] and changes by at most j_max dt per step; v_ref never goes
negative (at v_ref = 0 the window's acceleration is 0, see `window_speed`).

Manoeuvre fields (all optional; SI units):
    time_gap: 1.5 s       time headway at speed
    standstill: 3.0 m     gap kept at rest
    a_max: 1.5 m/s2       acceleration bound of the reference
    d_max: 5.0 m/s2       deceleration bound (positive number): hard braking, not comfort
    j_max: 5.0 m/s3       jerk bound of the reference
    k_gap: 0.2 1/s2       gap-error gain
    k_speed: 0.8 1/s      relative-speed gain
    range: 150 m          a lead farther than this is ignored
The `speed:` section keeps its meaning: it bounds the free-road profile only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from cosim.component import ComponentError, Port, Value
from controllers.road.builders import Road
from controllers.spec import spec_number

T_ROAD = 1.0     # s: time constant of the approach to the road profile's speed when no lead limits it
LEAD_INPUTS: tuple[Port, ...] = (
    Port("lead_x", unit="m", description="lead vehicle CG world x"),
    Port("lead_y", unit="m", description="lead vehicle CG world y"),
    Port("lead_vx", unit="m/s", description="lead vehicle longitudinal speed"),
)
FOLLOWING_OUTPUTS: tuple[Port, ...] = (
    Port("gap", unit="m", description="bumper-to-bumper gap to the lead, along the road"),
    Port("gap_ref", unit="m", description="desired gap standstill + time_gap * vx"),
    Port("a_follow", unit="m/s2", description="acceleration reference of the time-gap policy"),
)


@dataclass(frozen=True)
class TimeGapPolicy:
    """The constant-time-gap policy's parameters (module docstring); SI units."""

    time_gap: float = 1.5
    standstill: float = 3.0
    a_max: float = 1.5
    d_max: float = 5.0
    j_max: float = 5.0
    k_gap: float = 0.2
    k_speed: float = 0.8
    range: float = 150.0

    @classmethod
    def from_spec(cls, spec: Mapping, where: str) -> "TimeGapPolicy":
        """The policy fields present in a manoeuvre spec (others default), all > 0."""
        return cls(**{f.name: spec_number(spec[f.name], f"{where}.{f.name}", positive=True)
                      for f in fields(cls) if f.name in spec})

    def desired_gap(self, v: float) -> float:
        """g* = standstill + time_gap * v (v floored at 0), m."""
        return self.standstill + self.time_gap * max(v, 0.0)

    def demand(self, gap: float, v: float, v_lead: float) -> float:
        """a_des from gap and speed feedback, before the road cap and the bounds, m/s2."""
        return self.k_gap * (gap - self.desired_gap(v)) + self.k_speed * (v_lead - v)


FOLLOWING_KEYS = frozenset(f.name for f in fields(TimeGapPolicy))


class TimeGapSpeed:
    """The policy's state: the speed reference v_ref and its acceleration a (module docstring)."""

    def __init__(self, policy: TimeGapPolicy, v0: float) -> None:
        self.policy = policy
        self.v = max(float(v0), 0.0)
        self.a = 0.0

    def advance(self, a_des: float | None, v_road: float, a_road: float, dt: float) -> tuple[float, float]:
        """One step of dt seconds; a_des None: no lead in range. Returns (v_ref, a).

        Args:
            a_des: the policy's demand (TimeGapPolicy.demand), or None for a free road.
            v_road, a_road: the road profile's speed and acceleration at the vehicle.
            dt: time since the previous step, s (> 0).
        """
        p = self.policy
        cap = a_road + (v_road - self.v) / T_ROAD
        target = cap if a_des is None else min(a_des, cap)
        target = min(p.a_max, max(-p.d_max, target))
        target = max(target, self._landing(dt))
        jump = p.j_max * dt
        a = self.a + min(jump, max(-jump, target - self.a))
        self.v = max(self.v + 0.5 * (self.a + a) * dt, 0.0)
        self.a = a
        return self.v, a


    def _landing(self, dt: float) -> float:
        """The hardest braking a after this step that can still fade out at j_max before v_ref = 0.

        a^2 <= 2 j_max v at the end of the step, with v = v_ref + (a_prev + a) dt / 2
        (the trapezoid of `advance`): the lower root of that quadratic in a.
        """
        j = self.policy.j_max
        c = max(self.v + 0.5 * self.a * dt, 0.0)
        return 0.5 * (j * dt - math.sqrt(j * j * dt * dt + 8.0 * j * c))


def window_speed(ahead: np.ndarray, v_ref: float, a_ref: float, v_road: np.ndarray,
                 a_road: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The window's speed and acceleration: the policy's reference carried along, capped by the road.

    Ahead of the vehicle the reference keeps its acceleration over distance,
    v(sigma) = sqrt(v_ref^2 + 2 a_ref sigma) (0 once that would stop), so the
    controller reading the window at its foot point sees it evolve between
    planner steps; behind the vehicle it is v_ref. Where the road's profile is
    slower, the road's speed and acceleration are used; where v = 0, a = 0.

    Args:
        ahead: window arc lengths from the vehicle's foot point, m (negative behind).
        v_ref, a_ref: the policy's speed and acceleration at the vehicle.
        v_road, a_road: the road profile's speed and acceleration at the window points.
    """
    sq = v_ref * v_ref + 2.0 * a_ref * np.maximum(ahead, 0.0)
    v = np.sqrt(np.maximum(sq, 0.0))
    a = np.where(v > 0.0, a_ref, 0.0)
    road = v_road < v
    return np.where(road, v_road, v), np.where(road, a_road, a)


class Follower:
    """The planner's vehicle-following part: lead projection, gap, policy, window speeds.

    Args:
        road: the planner's road; policy: the time-gap policy;
        vehicle_length: both cars' length, m (the gap is bumper to bumper);
        off_road: the lead may be this far from the reference line before it is an error, m.
    """

    def __init__(self, road: Road, policy: TimeGapPolicy, vehicle_length: float, off_road: float) -> None:
        self.road, self.policy, self.length, self.off_road = road, policy, vehicle_length, off_road
        self.lead = (0.0, 0.0, 0.0)
        self.reset()

    def reset(self) -> None:
        """Forget the lead's track and the policy's state (the planner's initialize)."""
        self.speed: TimeGapSpeed | None = None
        self.s_lead: float | None = None
        self.t_prev = 0.0

    def read(self, t: float, inputs: Mapping[str, Value]) -> None:
        """Keep the lead's (x, y, vx) from the inputs, rejecting missing or non-finite values."""
        values = []
        for port in LEAD_INPUTS:
            if port.name not in inputs:
                raise ComponentError(f"input {port.name!r} missing at t = {t}")
            value = float(inputs[port.name])
            if not math.isfinite(value):
                raise ComponentError(f"input {port.name!r} is {value} at t = {t}")
            values.append(value)
        self.lead = (values[0], values[1], values[2])

    def gap(self, t: float, s_ego: float) -> float:
        """Bumper-to-bumper gap along the road from the follower at progress s_ego, m."""
        ref = self.road.reference
        guess = None if self.s_lead is None else float(ref.wrap(self.s_lead))
        proj = ref.project(self.lead[0], self.lead[1], s_guess=guess)
        if proj.distance > self.off_road and guess is not None:      # a jump: search the whole road again
            proj = ref.project(self.lead[0], self.lead[1])
        if proj.distance > self.off_road:
            raise ComponentError(f"at t = {t}: lead vehicle at ({self.lead[0]:.2f}, {self.lead[1]:.2f}) is "
                                 f"{proj.distance:.2f} m from the road's reference line: it has left the road")
        ahead = proj.s - s_ego
        if self.road.closed:
            length = self.road.length
            ahead = (ahead + 0.5 * length) % length - 0.5 * length
        self.s_lead = s_ego + ahead
        return ahead - self.length

    def apply(self, t: float, out: dict[str, Value], s_ego: float, vx: float, ahead: np.ndarray) -> None:
        """Replace the recommended window's speeds and v_ref in `out`; add gap, gap_ref, a_follow.

        Args:
            t: the step's time; out: the planner's outputs (road profile in ref_v, ref_a, v_ref).
            s_ego: follower's progress along the reference line; vx: its speed.
            ahead: the ref window's arc lengths from the follower's foot point, m.
        """
        gap = self.gap(t, s_ego)
        v_road = float(out["v_ref"])
        a_road = float(np.interp(0.0, ahead, out["ref_a"]))
        if self.speed is None:               # initialize: the reference starts at the vehicle's speed
            self.speed = TimeGapSpeed(self.policy, min(vx, v_road))
            v_ref, a_ref = self.speed.v, 0.0
        else:
            in_range = 0.0 <= gap + self.length <= self.policy.range
            demand = self.policy.demand(gap, vx, self.lead[2]) if in_range else None
            v_ref, a_ref = self.speed.advance(demand, v_road, a_road, t - self.t_prev)
        self.t_prev = t
        out["ref_v"], out["ref_a"] = window_speed(ahead, v_ref, a_ref, out["ref_v"], out["ref_a"])
        out["v_ref"] = min(v_ref, v_road)
        out["gap"] = gap
        out["gap_ref"] = self.policy.desired_gap(vx)
        out["a_follow"] = a_ref

