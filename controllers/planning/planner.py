"""The trajectory planner component: road, manoeuvre and speed profile to windows.

At initialize it projects the vehicle on the road, plans the manoeuvre's two
options (controllers.planning.manoeuvres) over the whole route and gives each a
low-energy speed profile along its own arc length (controllers.planning.speed_profile).
At every step (10 Hz by default) it tracks the vehicle's progress along the
road (warm-started projection, unwrapped over laps of a closed road; its Newton
iteration compiled by numba for a long run, controllers.road.compiled_path) and
samples both options into fixed-size windows (controllers.trajectory): the
recommended one on the `ref_*` ports, the alternative on `alt_*`. When the
run reads no `alt_*` output (`use_outputs`: not connected, not recorded), the
alternative is planned once, at initialize, and that window is held.

Window points are equally spaced in reference arc length, the first
`window_back` metres behind the vehicle's projection; the spacing grows if
needed so the window reaches at least `preview` plus two planner periods at
v_max ahead of the vehicle, measured along the trajectory itself. Window `s`
is the trajectory's own arc length from the first point (Simpson's rule on
d sigma/ds), `psi` is unwrapped and within pi of the vehicle's heading.

Scalar outputs: s_vehicle (progress along the reference line, m, unwrapped),
lateral_offset (vehicle CG left of the recommended trajectory, m), v_ref
(recommended speed at the vehicle), manoeuvre_state (0 keep, 1 lateral
transition under way, 2 braking to a stop, 3 held at rest), obstacle_distance
(to the next obstacle in the vehicle's lane, capped at obstacle_range).

A stop ends in finite time (controllers.planning.speed_profile, step 3). Once the
vehicle is in the stop's final segment (or past it) and slower than
HOLD_SPEED, the planner holds: state 3 for good, and the recommended window's
speed and acceleration are 0 everywhere, so the controller's reference is
rest exactly, even if the car stands a few centimetres short of the point.

Parameters in a scenario YAML, for example:
    road: {builder: two_lane, length: 600, radius: 200}     # or satory_standin, or
                                      # {reference: {segments: [...]}, lanes: 2, lane_width: 3.5}
    lane: 0
    manoeuvre: {type: obstacle_avoidance, margin: 0.5,
                obstacles: [{s: 250, lane: 0, length: 4, width: 2}]}
    speed: {v_max: 12, a_lat_max: 2, a_max: 1, d_max: 1.5, j_max: 1}
Obstacle and lane-change positions are reference arc lengths (first lap on a loop).

With `manoeuvre: {type: vehicle_following, ...}` the planner also has the
inputs lead_x, lead_y, lead_vx (the lead vehicle, connected from its plant)
and the outputs gap, gap_ref, a_follow; the recommended window's speed and
acceleration, and v_ref, come from the time-gap policy, capped by the road's
profile (controllers.planning.following).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Set

import numpy as np

from cosim.component import Component, ComponentError, ModelReference, Port, Value, frozen_copy
from controllers.road import compiled_path
from controllers.road.geometry import SpecError, spec_number
from controllers.planning.following import FOLLOWING_OUTPUTS, LEAD_INPUTS, Follower
from controllers.spec import MAX_LENGTH, MAX_REACH
from controllers.planning.manoeuvres import (LateralPlan, ManoeuvrePlan, Option, Transition, offset_profile,
                                   plan_manoeuvre, transition_length)
from controllers.road.builders import Road, canonical_key, frenet_from_base, keep, road_from_spec
from controllers.planning.speed_profile import SpeedLimits, plan_speed
from controllers.trajectory import FIELDS, WINDOW_POINTS, window_ports

ROUTE_DS = 0.25        # m, reference grid the route is laid out on (window points are grid points)
PROFILE_DS = 0.5       # m, arc-length grid of the speed profiles
STATE_KEEP, STATE_CHANGING, STATE_STOPPING, STATE_HOLD = 0.0, 1.0, 2.0, 3.0
HOLD_SPEED = 0.01      # m/s: below it, in the stop's final segment or past it, the vehicle is held
_cumsum = np.add.accumulate     # np.cumsum of a 1-D array without its Python wrapper (every step)
_WINDOW_KEYS: dict[str, tuple[str, ...]] = {}    # port names of a window per prefix, made once
# the routes laid out in this process (grid, recommended and alternative plans), by the
# planner's parameters and the vehicle's first state: the samples of a sweep that vary
# anything else (a controller gain, a plant parameter that leaves the start alone) lay
# them out once per worker (the speed profiles are most of a planner's start-up, ~45 ms
# on the Satory loop). They are only read after initialize, by every planner that has them.
ROUTES_KEPT = 4
_routes: dict[tuple[str, ...], tuple["RouteGrid", "RoutePlan", "RoutePlan | None"]] = {}


class RouteGrid:
    """The road's reference line sampled every ROUTE_DS over the route and its margins."""

    def __init__(self, road: Road, s_first: float, s_last: float):
        """Sample the reference line of `road` on [s_first, s_last] (reference arc length)."""
        n = int(np.ceil((s_last - s_first) / ROUTE_DS)) + 1
        self.road = road
        self.s = s_first + ROUTE_DS * np.arange(n)
        x, y, psi, k = road.reference.evaluate(self.s)
        self.base = (x, y, np.unwrap(psi), k, road.reference.dkappa(self.s))
        self.trig = (np.sin(self.base[2]), np.cos(self.base[2]))
        self._s_first = float(self.s[0])

    def index(self, s: float) -> int:
        """Index of the last grid point at or before s."""
        return math.floor((s - self._s_first) / ROUTE_DS + 1e-9)

    def trajectory(self, lateral: LateralPlan, sl: slice = slice(None)):
        """x, y, psi, kappa and own arc length (from the slice start) of a lateral plan."""
        return self.layout(lateral.evaluate(self.s[sl]), sl)

    def layout(self, profile: tuple[np.ndarray, np.ndarray, np.ndarray], sl: slice):
        """x, y, psi, kappa and own arc length (from the slice start) of an offset profile.

        Args:
            profile: (d, dd/ds, d2d/ds2) at the grid points sl.
            sl: a contiguous slice of the grid.
        """
        x0, y0, psi0, k, dk = self.base
        x, y, psi, kappa, g = frenet_from_base((x0[sl], y0[sl], psi0[sl], k[sl], dk[sl]), *profile, self.s[sl],
                                               trig=(self.trig[0][sl], self.trig[1][sl]))
        sigma = np.empty(g.size)
        sigma[0] = 0.0
        _cumsum(0.5 * ROUTE_DS * (g[1:] + g[:-1]), out=sigma[1:])
        return x, y, psi, kappa, sigma


class RoutePlan:
    """One option laid out on the route grid: geometry, own arc length, speed."""

    def __init__(self, grid: RouteGrid, option: Option, s_start: float, s_end: float,
                 limits: SpeedLimits, from_rest: bool, stop_at_end: bool, v_start: float):
        """Lay out `option`; its speed profile runs from s_start to s_end (or its stop point).

        Args:
            grid: the sampled road; option: lateral plan and stop point.
            s_start, s_end: route extent in reference arc length.
            limits: speed limits; from_rest, v_start: initial condition.
            stop_at_end: stop at s_end (the option's stop point always stops).
        """
        stop = stop_at_end
        if option.stop_s is not None and option.stop_s < s_end:
            s_end, stop = option.stop_s, True
        if s_end - s_start < 2 * PROFILE_DS:
            raise SpecError(f"route from s = {s_start:.2f} m to {s_end:.2f} m is too short "
                            "(a stop point behind the vehicle?)")
        self.lateral = option.lateral
        self.x, self.y, self.psi, kappa, self.sigma = grid.trajectory(option.lateral)
        self.d = option.lateral.evaluate(grid.s)[0]
        sig0, sig1 = np.interp([s_start, s_end], grid.s, self.sigma)
        steps = int(np.ceil((sig1 - sig0) / PROFILE_DS - 1e-9))
        ds = (sig1 - sig0) / steps             # at most PROFILE_DS, so the profile ends exactly at sig1
        sig_u = sig0 + ds * np.arange(steps + 1)
        profile = plan_speed(np.interp(sig_u, self.sigma, kappa), ds, limits, from_rest, stop,
                             s0=sig0, v_start=None if from_rest else v_start)
        self.profile = profile                    # on the trajectory's own arc length
        self.v, self.a = profile.at(self.sigma)
        self.kappa = kappa
        self.stops = stop
        self.brake_from = self.final_from = np.inf
        if stop:
            going = np.nonzero(profile.a[:-1] > -1e-6)[0]       # the last point (at rest) has a = 0 too
            at = profile.s[going[-1]] if going.size else sig0
            self.brake_from = float(np.interp(at, self.sigma, grid.s))
            final = profile.s[-1] if profile.final_from is None else profile.final_from
            self.final_from = float(np.interp(final, self.sigma, grid.s))

    def window(self, idx: slice, psi_shift: float, prefix: str) -> dict[str, np.ndarray]:
        """Port values `<prefix>_<field>` of the window made of the grid points idx (a slice),
        headings shifted by psi_shift (2 pi k). Arrays may be views: the hosts copy them."""
        sigma = self.sigma[idx]
        return window_signals(prefix, self.x[idx], self.y[idx], self.psi[idx] + psi_shift, self.kappa[idx],
                              sigma - sigma[0], self.v[idx], self.a[idx])


def _parameters_key(parameters: dict[str, object]) -> str | None:
    """A planner's parameters as the key of its routes in `_routes` (None: nothing kept)."""
    return canonical_key(parameters, parameters["road"])


def window_signals(prefix: str, *fields: np.ndarray) -> dict[str, np.ndarray]:
    """The port values of one window from its fields in controllers.trajectory.FIELDS order."""
    names = _WINDOW_KEYS.get(prefix)
    if names is None:
        names = _WINDOW_KEYS[prefix] = tuple(f"{prefix}_{name}" for name, _, _ in FIELDS)
    return dict(zip(names, fields))


class Planner(Component):
    """Trajectory planner: recommended and alternative windows from road + manoeuvre."""

    default_period = 0.1
    parameters_model = ModelReference("controllers.planning.parameters:PlannerParameters")
    inputs = (Port("x", unit="m", description="vehicle CG world x"),
              Port("y", unit="m", description="vehicle CG world y"),
              Port("psi", unit="rad", description="vehicle yaw angle"),
              Port("vx", unit="m/s", description="vehicle longitudinal speed"))
    outputs = (window_ports("ref", role="recommended") + window_ports("alt", role="alternative") + (
        Port("s_vehicle", unit="m", description="vehicle progress along the road reference line"),
        Port("lateral_offset", unit="m", description="vehicle CG left of the recommended trajectory"),
        Port("v_ref", unit="m/s", description="recommended speed at the vehicle"),
        Port("manoeuvre_state", description="0 keep, 1 lateral transition, 2 braking to a stop, 3 held at rest"),
        Port("obstacle_distance", unit="m", description="to the next obstacle in the vehicle's lane")))

    def __init__(self, road="satory_standin", lane=0, manoeuvre=None, speed=None,
                 start_from_rest=None, stop_at_end=True, laps=1, distance=None,
                 window_spacing=0.5, window_back=3.0, preview=5.0, planner_period=0.1,
                 launch_offset=2.0, obstacle_range=1000.0, off_road=20.0, **unknown):
        """Check and keep the parameters (all plain YAML values).

        Args:
            road: builder name, {builder: ..., args}, or {reference, lanes, lane_width}.
            lane: starting lane (0 = reference line).
            manoeuvre: manoeuvre spec (controllers.planning.manoeuvres.plan_manoeuvre); None: keep lane.
            speed: speed limits {v_max, a_lat_max, a_max, d_max, j_max}.
            start_from_rest: start the profile at v = 0 (None: if vx < 0.1 m/s at t0).
            stop_at_end: stop at the end of the route.
            laps: laps of a closed road; distance: route length on an open road (None: to its end).
            window_spacing: minimum spacing of window points, m.
            window_back: how far behind the vehicle the window starts, m.
            preview: the controller's look-ahead distance the window must cover, m.
            planner_period: this component's period, s (for the window coverage).
            launch_offset: from rest, the profile's v = 0 point lies this far behind the vehicle, m.
            obstacle_range: cap of obstacle_distance, m.
            off_road: the run stops when the vehicle is this far outside the road's edges, m.
            unknown: any other name is an error listing the known ones.
        """
        if unknown:
            known = [n for n in Planner.__init__.__code__.co_varnames[1:Planner.__init__.__code__.co_argcount]]
            first = sorted(unknown)[0]  # named first, so the scenario's line of it is shown
            raise ComponentError(f"{first}: unknown parameters {sorted(unknown)} (known: {', '.join(known)})")
        try:
            self.road = compiled_path.for_this_component(road_from_spec(road))    # its per-step search (COSIM_JIT)
            self.lane = self.road.check_lane(lane, "lane")
            self.limits = SpeedLimits.from_spec(speed)
            self.manoeuvre_spec = manoeuvre
            self.plan: ManoeuvrePlan = plan_manoeuvre(self.road, self.lane, manoeuvre, self.limits.v_max)
            if not isinstance(stop_at_end, bool) or not (start_from_rest is None or isinstance(start_from_rest, bool)):
                raise SpecError(f"stop_at_end / start_from_rest: expected true or false (start_from_rest may be "
                                f"null), got {stop_at_end!r} / {start_from_rest!r}")
            self.stop_at_end, self.start_from_rest = stop_at_end, start_from_rest
            if isinstance(laps, bool) or not isinstance(laps, int) or laps < 1:
                raise SpecError(f"laps: expected an integer >= 1, got {laps!r}")
            if self.road.closed and laps * self.road.length > MAX_LENGTH:  # the route is sampled
                raise SpecError(f"laps: {laps} laps of {self.road.length:.6g} m make a route "
                                f"longer than {MAX_LENGTH:g} m")
            self.laps = laps
            self.distance = None if distance is None else spec_number(
                distance, "distance", positive=True, at_most=MAX_LENGTH)
            self.back = spec_number(window_back, "window_back", positive=True, at_most=MAX_REACH)
            self.launch = spec_number(launch_offset, "launch_offset", positive=True, at_most=MAX_REACH)
            self.range = spec_number(obstacle_range, "obstacle_range", positive=True)
            self.off_road = spec_number(off_road, "off_road", positive=True)
            self.step_pts = self._spacing(
                spec_number(window_spacing, "window_spacing", positive=True, at_most=MAX_REACH),
                spec_number(preview, "preview", positive=True, at_most=MAX_REACH),
                spec_number(planner_period, "planner_period", positive=True, at_most=60.0))
        except SpecError as exc:
            raise ComponentError(f"parameter {exc}") from None
        self.progress = self.offset = 0.0
        self.road_limit = float(max(np.abs(self.road.edges()))) + self.off_road
        self.follower: Follower | None = None
        if self.plan.following is not None:
            self.follower = Follower(self.road, self.plan.following, self.plan.comfort.vehicle_length,
                                     self.road_limit)
            self.inputs, self.outputs = Planner.inputs + LEAD_INPUTS, Planner.outputs + FOLLOWING_OUTPUTS
        self.ref_route: RoutePlan | None = None
        self.alt_route: RoutePlan | None = None
        self._routes_key = _parameters_key(
            {"road": road, "lane": lane, "manoeuvre": manoeuvre, "speed": speed,
             "start_from_rest": start_from_rest, "stop_at_end": stop_at_end, "laps": laps,
             "distance": distance, "window_spacing": window_spacing, "window_back": window_back,
             "preview": preview, "planner_period": planner_period, "launch_offset": launch_offset,
             "obstacle_range": obstacle_range, "off_road": off_road})
        self._alt_offset: float | None = None      # lateral offset of plan.alt_lane, looked up once
        self.holding = False
        self.alt_read = True  # False: nothing reads alt_* (use_outputs), the first window is held
        self._alt_held: dict[str, np.ndarray] | None = None

    def _spacing(self, minimum: float, preview: float, period: float) -> int:
        """Window spacing, in route grid steps, that covers the required reach."""
        reach = self.back + preview + 2.0 * period * self.limits.v_max
        ref = self.road.reference
        kmax = float(np.max(np.abs(np.concatenate([ref.k0, ref.k1]))))
        widest = (self.road.lanes - 0.5) * self.road.lane_width
        shrink = max(1.0 - kmax * widest, 0.1)       # inner lanes are shorter than the reference
        spacing = max(minimum, reach / (WINDOW_POINTS - 1) / shrink)
        return int(np.ceil(spacing / ROUTE_DS - 1e-9))

    # ---- component protocol ---------------------------------------------
    def use_outputs(self, names: Set[str]) -> None:
        """Plan the alternative window only when the run reads it (its dynamic lane change,
        planned afresh at every step, is most of a lane-keeping step); otherwise the first
        one is held."""
        self.alt_read = any(name.startswith("alt_") for name in names)

    def initialize(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Locate the vehicle, lay out both options over the route, return the first windows."""
        x, y, psi, vx = self._read(t0, inputs)
        proj = self.road.reference.project(x, y)
        s0 = proj.s - self.road.length if self.road.closed and proj.s > 0.5 * self.road.length else proj.s
        self.progress = s0
        self._check_on_road(t0, x, y, proj.distance)
        from_rest = vx < 0.1 if self.start_from_rest is None else self.start_from_rest
        start = s0 - (self.launch if from_rest else self.back)
        if self.road.closed:
            end = s0 + self.laps * self.road.length
        else:
            end = self.road.length if self.distance is None else min(self.road.length, s0 + self.distance)
        key = None if self._routes_key is None else (self._routes_key, *(float(v).hex() for v in (t0, x, y, psi, vx)))
        kept = _routes.get(key) if key is not None else None
        if kept is None:
            kept = self._lay_out(t0, start, end, from_rest, vx)
            if key is not None:
                keep(_routes, key, kept, ROUTES_KEPT)
        self.grid, self.ref_route, self.alt_route = kept
        self.offset = proj.lateral
        self.holding = False
        self._alt_held = None
        if self.follower is not None:
            self.follower.reset()
            self.follower.read(t0, inputs)
        return self._outputs(t0, psi, vx)

    def _lay_out(self, t0: float, start: float, end: float, from_rest: bool,
                 vx: float) -> tuple[RouteGrid, RoutePlan, RoutePlan | None]:
        """The route grid and both options laid out on it, from `start` to `end`."""
        span = self.step_pts * ROUTE_DS * (WINDOW_POINTS - 1)
        grid = RouteGrid(self.road, start - self.back - 10.0, end + span + 10.0)
        try:
            ref = RoutePlan(grid, self.plan.ref, start, end, self.limits, from_rest, self.stop_at_end, vx)
            alt = None if self.plan.alt is None else RoutePlan(grid, self.plan.alt, start, end, self.limits,
                                                               from_rest, self.stop_at_end, vx)
        except SpecError as exc:
            raise ComponentError(f"at t = {t0}: {exc}") from None
        return grid, ref, alt

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Track the vehicle's progress and return both windows and the scalars."""
        if self.ref_route is None:
            raise ComponentError("step called before initialize")
        x, y, psi, vx = self._read(t, inputs)
        proj = self.road.reference.project(x, y, s_guess=float(self.road.reference.wrap(self.progress)))
        if proj.distance > self.road_limit:
            proj = self.road.reference.project(x, y)      # a jump: search the whole road again
        if self.road.closed:
            length = self.road.length
            delta = (proj.s - self.progress % length + 0.5 * length) % length - 0.5 * length
            self.progress += delta
        else:
            self.progress = proj.s
        self._check_on_road(t, x, y, proj.distance)
        self.offset = proj.lateral
        if self.follower is not None:
            self.follower.read(t, inputs)
        return self._outputs(t, psi, vx)

    # ---- helpers ----------------------------------------------------------
    @staticmethod
    def _read(t: float, inputs: Mapping[str, Value]) -> tuple[float, float, float, float]:
        """The four inputs as floats, rejecting missing or non-finite values."""
        out = []
        for name in ("x", "y", "psi", "vx"):
            if name not in inputs:
                raise ComponentError(f"input {name!r} missing at t = {t}")
            value = float(inputs[name])
            if not math.isfinite(value):
                raise ComponentError(f"input {name!r} is {value} at t = {t}")
            out.append(value)
        return out[0], out[1], out[2], out[3]

    def _check_on_road(self, t: float, x: float, y: float, distance: float) -> None:
        """Stop with a clear message when the vehicle is far off the road (or past its end)."""
        limit = self.road_limit
        if distance > limit:
            raise ComponentError(f"at t = {t}: vehicle at ({x:.2f}, {y:.2f}) is {distance:.2f} m from the "
                                 f"road's reference line (more than {limit:.2f} m): it has left the road")

    def _indices(self, t: float) -> slice:
        """Grid indices of the window points at the current progress (a slice)."""
        first = self.grid.index(self.progress - self.back)
        last = first + self.step_pts * (WINDOW_POINTS - 1)
        if first < 0 or last >= self.grid.s.size:
            raise ComponentError(f"at t = {t}: vehicle at s = {self.progress:.2f} m has left the planned "
                                 f"route [{self.grid.s[0]:.2f}, {self.grid.s[-1]:.2f}] m")
        return slice(first, last + 1, self.step_pts)

    def _alt_window(self, idx: slice, vx: float, psi_shift: float, d_now: float) -> dict[str, np.ndarray]:
        """The alternative window: planned now, or the held first one when nothing reads it."""
        if self._alt_held is not None:
            return self._alt_held
        alt = (self._dynamic_alt(idx, vx, psi_shift, d_now) if self.alt_route is None
               else self.alt_route.window(idx, psi_shift, "alt"))
        if not self.alt_read:
            alt = self._alt_held = {name: frozen_copy(value) for name, value in alt.items()}  # sent once
        return alt

    def _dynamic_alt(self, idx: slice, vx: float, psi_shift: float, d_now: float) -> dict[str, np.ndarray]:
        """Window of the lane change to plan.alt_lane starting at the vehicle's progress.

        Args:
            idx: the window's grid points; vx: vehicle speed, m/s.
            psi_shift: heading shift (2 pi k); d_now: recommended offset at the vehicle, m.
        """
        d_to = self._alt_offset
        if d_to is None:
            d_to = self._alt_offset = self.road.lane_offset(self.plan.alt_lane)
        speed = min(max(vx, 3.0), self.limits.v_max)
        length = transition_length(d_to - d_now, speed, self.plan.comfort)
        sl = slice(idx.start, idx.stop)
        profile = offset_profile(d_now, (Transition(self.progress, length, d_now, d_to),), self.grid.s[sl])
        x, y, psi, kappa, sigma = self.grid.layout(profile, sl)
        sub = slice(None, None, idx.step)
        return window_signals("alt", x[sub], y[sub], psi[sub] + psi_shift, kappa[sub], sigma[sub],
                              self.ref_route.v[idx], self.ref_route.a[idx])

    def _outputs(self, t: float, psi: float, vx: float) -> dict[str, Value]:
        """Both windows and the scalar outputs at the current progress."""
        idx = self._indices(t)
        # on Python floats: the same IEEE operations as on numpy's scalar, without its overhead
        shift = 2 * np.pi * round((psi - float(self.ref_route.psi[idx.start])) / (2 * np.pi))
        d_now = float(np.interp(self.progress, self.grid.s, self.ref_route.d))
        out: dict[str, Value] = self.ref_route.window(idx, shift, "ref")
        out.update(self._alt_window(idx, vx, shift, d_now))
        out["s_vehicle"] = float(self.progress)
        out["lateral_offset"] = float(self.offset - d_now)
        out["v_ref"] = float(np.interp(self.progress, self.grid.s, self.ref_route.v))
        if self.follower is not None:
            sigma = self.ref_route.sigma
            at = float(np.interp(self.progress, self.grid.s, sigma)) - sigma[idx.start]
            self.follower.apply(t, out, self.progress, vx, out["ref_s"] - at)
        out["manoeuvre_state"] = self._update_state(vx)
        if self.holding:      # stopped: the reference is rest, exactly, wherever the car stands
            out["ref_v"] = np.zeros(WINDOW_POINTS)
            out["ref_a"] = np.zeros(WINDOW_POINTS)
            out["v_ref"] = 0.0
        out["obstacle_distance"] = self._obstacle_distance(self.offset)
        return out

    def _update_state(self, vx: float) -> float:
        """manoeuvre_state at the current progress; enters (and latches) the hold.

        Hold: the route stops, the vehicle is in the stop's final segment or past
        it and slower than HOLD_SPEED.
        """
        if self.holding:
            return STATE_HOLD
        if self.plan.ref.lateral.active(self.progress):
            return STATE_CHANGING
        if self.ref_route.stops and self.progress >= self.ref_route.brake_from:
            if self.progress >= self.ref_route.final_from and vx < HOLD_SPEED:
                self.holding = True
                return STATE_HOLD
            return STATE_STOPPING
        return STATE_KEEP

    def _obstacle_distance(self, d_vehicle: float) -> float:
        """Distance to the next obstacle in the vehicle's lane, capped at obstacle_range."""
        if not self.plan.obstacles:
            return self.range
        lane = self.road.lane_at(d_vehicle)
        ahead = [o.s - self.progress for o in self.plan.obstacles
                 if o.lane == lane and o.s + o.length > self.progress]
        return float(min([self.range] + [max(a, 0.0) for a in ahead]))
