"""Manoeuvres as lateral offset plans d(s) on a road, plus an optional stop point.

Every manoeuvre is described in road coordinates: the lateral offset d(s) of
the planned trajectory from the road's reference line, made of constant
stretches joined by quintic transitions (zero lateral slope and curvature at
both ends), and an arc length where the vehicle must have stopped, if any.
Each manoeuvre yields two options like the paper: the recommended one (which
the controller follows) and the alternative.

    lane_keeping        ref: follow the lane centre; alt: change lane now
    lane_change         ref: change to `to_lane` starting at s = `at`; alt: stay
    obstacle_avoidance  static obstacles {s, lane, length, width}: go around
                        with a lateral margin when the next lane is free,
                        otherwise stop `gap` metres before; alt: the other choice
    vehicle_following   the lane_keeping options; the speed follows a lead vehicle
                        with a constant-time-gap policy (controllers.planning.following)

A transition over length L with lateral change D at speed v has a peak lateral
acceleration 10/sqrt(3) D v^2 / L^2 and a peak lateral jerk 60 D v^3 / L^3;
`transition_length` picks the shortest L keeping both within comfort.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from controllers.planning.following import FOLLOWING_KEYS, TimeGapPolicy
from controllers.road.builders import Road
from controllers.spec import SpecError, spec_number

QUINTIC_PEAK_CURV = 10.0 / np.sqrt(3.0)    # max |p''| of p = 10t^3 - 15t^4 + 6t^5
QUINTIC_PEAK_JERK = 60.0                   # max |p'''|, at the ends


@dataclass(frozen=True)
class Transition:
    """A quintic change of lateral offset from d0 to d1 over [s0, s0 + length]."""

    s0: float
    length: float
    d0: float
    d1: float

    @property
    def s1(self) -> float:
        """Arc length where the transition ends."""
        return self.s0 + self.length


@dataclass(frozen=True)
class LateralPlan:
    """Lateral offset d(s): `d_start` before the first transition, then each in turn.

    Transitions are sorted, do not overlap, and each starts at the offset the
    previous one ended at.
    """

    d_start: float
    transitions: tuple[Transition, ...] = ()

    def __post_init__(self):
        d, end = self.d_start, -np.inf
        for i, tr in enumerate(self.transitions):
            if tr.s0 < end or not tr.length > 0 or abs(tr.d0 - d) > 1e-9:
                raise SpecError(f"manoeuvre transitions overlap or do not chain (transition {i} "
                                f"at s = {tr.s0:.2f} m)")
            d, end = tr.d1, tr.s1

    def evaluate(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(d, dd/ds, d2d/ds2) at reference arc lengths s (array).

        The transitions chain without overlapping, so d is d_start plus the
        sum of every transition's change times its quintic shape, clamped to
        0 before and 1 after it.
        """
        return offset_profile(self.d_start, self.transitions, s)

    def active(self, s: float) -> bool:
        """True while s lies inside a transition."""
        return any(tr.s0 <= s < tr.s1 for tr in self.transitions)


def offset_profile(d_start: float, transitions: Sequence[Transition], s) -> tuple[np.ndarray, ...]:
    """(d, dd/ds, d2d/ds2) at stations s of d_start followed by chained transitions.

    LateralPlan.evaluate without building (and checking) a plan, for the
    planner's per-step lane change.

    Args:
        d_start: offset before the first transition, m.
        transitions: sorted, chained, non-overlapping (as LateralPlan checks).
        s: reference arc lengths (array-like), m.
    """
    s = np.asarray(s, dtype=float)
    d = np.empty(s.shape)
    d[...] = float(d_start)
    d1, d2 = np.zeros(s.shape), np.zeros(s.shape)
    for tr in transitions:
        t = (s - tr.s0) * (1.0 / tr.length)
        np.maximum(t, 0.0, out=t)      # clip to [0, 1]: np.clip costs more than both at this size
        np.minimum(t, 1.0, out=t)
        tt = t * t
        omt = 1.0 - t
        big = tr.d1 - tr.d0
        d += big * tt * t * (10.0 + t * (6.0 * t - 15.0))
        d1 += (30.0 * big / tr.length) * tt * omt * omt
        d2 += (60.0 * big / tr.length ** 2) * t * omt * (1.0 - 2.0 * t)
    return d, d1, d2


@dataclass(frozen=True)
class Option:
    """One planned trajectory in road terms: lateral plan and stop point (None: no stop)."""

    lateral: LateralPlan
    stop_s: float | None = None


@dataclass(frozen=True)
class Obstacle:
    """A static box on the road: from s to s + length, `width` wide, centred on a lane.

    Attributes:
        s, length: longitudinal extent along the reference line, m.
        lane: lane index; offset: extra lateral shift of its centre (left +), m.
        width: lateral size, m.
    """

    s: float
    lane: int
    length: float
    width: float
    offset: float = 0.0

    def centre(self, road: Road) -> float:
        """Lateral offset of the obstacle's centre from the reference line."""
        return road.lane_offset(self.lane) + self.offset


@dataclass(frozen=True)
class Comfort:
    """Lateral comfort of manoeuvres and the vehicle's size for clearances.

    Attributes:
        a_lat: peak lateral acceleration added by a transition, m/s^2.
        j_lat: peak lateral jerk of a transition, m/s^3.
        min_length: shortest transition, m.
        margin: lateral clearance between vehicle and obstacle boxes, m.
        gap: longitudinal clearance between vehicle and obstacle boxes, m.
        vehicle_width, vehicle_length: the vehicle's box, m (CG at its centre).
    """

    a_lat: float = 1.5
    j_lat: float = 2.0
    min_length: float = 20.0
    margin: float = 0.5
    gap: float = 5.0
    vehicle_width: float = 1.8
    vehicle_length: float = 4.5


@dataclass(frozen=True)
class ManoeuvrePlan:
    """What the planner needs from a manoeuvre.

    Attributes:
        kind: manoeuvre type name.
        ref: the recommended option.
        alt: the alternative option; None means "change to `alt_lane` from
            wherever the vehicle is", rebuilt at every planning step.
        alt_lane: target lane of that dynamic alternative.
        obstacles: the static obstacles.
        comfort: the comfort limits the manoeuvre was planned with.
        following: the time-gap policy of vehicle_following (None for the others).
    """

    kind: str
    ref: Option
    alt: Option | None
    alt_lane: int
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)
    comfort: Comfort = field(default_factory=Comfort)
    following: TimeGapPolicy | None = None


def transition_length(delta: float, v: float, comfort: Comfort) -> float:
    """Shortest quintic length for a lateral change `delta` at speed v within comfort.

    Args:
        delta: lateral offset change, m.
        v: speed during the transition, m/s.
        comfort: lateral acceleration and jerk limits and the minimum length.
    """
    delta = abs(delta)
    by_acc = v * np.sqrt(QUINTIC_PEAK_CURV * delta / comfort.a_lat)
    by_jerk = v * np.cbrt(QUINTIC_PEAK_JERK * delta / comfort.j_lat)
    return float(max(comfort.min_length, by_acc, by_jerk))


def _neighbour(road: Road, lane: int) -> int:
    """The lane to change to: the left one if it exists, else the right one (or itself)."""
    if lane + 1 < road.lanes:
        return lane + 1
    return lane - 1 if lane > 0 else lane


def _blocks(road: Road, obs: Obstacle, d: float, comfort: Comfort) -> bool:
    """True if a vehicle centred at lateral offset d cannot pass the obstacle with the margin."""
    reach = 0.5 * (obs.width + comfort.vehicle_width) + comfort.margin
    return abs(obs.centre(road) - d) < reach - 1e-9


def _avoidance(road: Road, lane: int, obs: Obstacle, others, v: float, comfort: Comfort):
    """Transitions going around `obs` from `lane`, and whether that path is free."""
    d_lane = road.lane_offset(lane)
    side = _neighbour(road, lane)
    if side == lane:
        return None, False
    sign = 1.0 if side > lane else -1.0
    clear = obs.centre(road) + sign * (0.5 * (obs.width + comfort.vehicle_width) + comfort.margin)
    target = max(road.lane_offset(side), clear) if sign > 0 else min(road.lane_offset(side), clear)
    length = transition_length(target - d_lane, v, comfort)
    half = 0.5 * comfort.vehicle_length + comfort.gap
    s_in = obs.s - half - length
    s_out = obs.s + obs.length + half
    trs = (Transition(s_in, length, d_lane, target), Transition(s_out, length, target, d_lane))
    right, left = road.edges()
    on_road = right <= target - 0.5 * comfort.vehicle_width and target + 0.5 * comfort.vehicle_width <= left
    free = on_road and not any(
        _blocks(road, o, target, comfort) and o.s < s_out + length and o.s + o.length > s_in
        for o in others if o is not obs)
    return trs, free


def plan_obstacles(road: Road, lane: int, obstacles: Sequence[Obstacle], v: float,
                   comfort: Comfort) -> tuple[Option, Option]:
    """Recommended and alternative options for static obstacles ahead in `lane`.

    Args:
        road: the road; lane: the ego lane.
        obstacles: the static obstacles (any lanes).
        v: design speed for transition lengths, m/s.
        comfort: comfort and clearance limits.
    """
    d_lane = road.lane_offset(lane)
    ref_trs: list[Transition] = []
    ref_stop = alt_stop = None
    alt_trs: list[Transition] | None = None
    for obs in sorted(obstacles, key=lambda o: o.s):
        if not _blocks(road, obs, d_lane, comfort):
            continue
        trs, free = _avoidance(road, lane, obs, obstacles, v, comfort)
        stop = obs.s - 0.5 * comfort.vehicle_length - comfort.gap
        if free:
            ref_trs.extend(trs)
            if alt_trs is None:
                alt_trs, alt_stop = list(ref_trs[:-2]), stop
            continue
        ref_stop = stop
        if alt_trs is None:
            alt_trs = list(ref_trs) + (list(trs) if trs else [])
            alt_stop = None if trs else stop
        break
    ref = Option(LateralPlan(d_lane, tuple(ref_trs)), ref_stop)
    alt = ref if alt_trs is None else Option(LateralPlan(d_lane, tuple(alt_trs)), alt_stop)
    return ref, alt


def _obstacle(spec, road: Road, where: str) -> Obstacle:
    """One obstacle from {s, lane, length, width[, offset]}."""
    if not isinstance(spec, Mapping) or not {"s", "lane", "length", "width"} <= set(spec) \
            or set(spec) - {"s", "lane", "length", "width", "offset"}:
        raise SpecError(f"{where}: expected keys s, lane, length, width (offset optional), got {spec!r}")
    return Obstacle(s=spec_number(spec["s"], where + ".s"), lane=road.check_lane(spec["lane"], where + ".lane"),
                    length=spec_number(spec["length"], where + ".length", positive=True),
                    width=spec_number(spec["width"], where + ".width", positive=True),
                    offset=spec_number(spec.get("offset", 0.0), where + ".offset"))


def comfort_from_spec(spec, where: str) -> Comfort:
    """Comfort fields present in a manoeuvre spec (others default)."""
    names = Comfort.__dataclass_fields__
    return Comfort(**{k: spec_number(spec[k], f"{where}.{k}", positive=(k != "margin"))
                      for k in names if k in spec})


def _lane_changes(road: Road, d_lane: float, spec, v_design: float, comfort: Comfort,
                  where: str) -> tuple[Transition, ...]:
    """Transitions of a lane_change spec: one {at, to_lane|to_offset, length} or a `changes` list."""
    items = spec["changes"] if "changes" in spec else [{k: v for k, v in spec.items()
                                                        if k in ("at", "to_lane", "to_offset", "length")}]
    if "changes" in spec and (set(spec) & {"at", "to_lane", "to_offset", "length"}):
        raise SpecError(f"{where}: give either changes or at/to_lane, not both")
    if not isinstance(items, Sequence) or isinstance(items, str) or not items:
        raise SpecError(f"{where}.changes: expected a non-empty list of {{at, to_lane, length}}")
    out, d = [], d_lane
    for i, item in enumerate(items):
        w = f"{where}.changes[{i}]" if "changes" in spec else where
        if not isinstance(item, Mapping) or "at" not in item or len({"to_lane", "to_offset"} & set(item)) != 1 \
                or set(item) - {"at", "to_lane", "to_offset", "length"}:
            raise SpecError(f"{w}: expected at, one of to_lane / to_offset, and optionally length; got {item!r}")
        target = (road.lane_offset(road.check_lane(item["to_lane"], w + ".to_lane")) if "to_lane" in item
                  else spec_number(item["to_offset"], w + ".to_offset"))
        length = (spec_number(item["length"], w + ".length", positive=True) if "length" in item
                  else transition_length(target - d, v_design, comfort))
        out.append(Transition(spec_number(item["at"], w + ".at"), length, d, target))
        d = target
    return tuple(out)


def plan_manoeuvre(road: Road, lane: int, spec, v_design: float, where: str = "manoeuvre") -> ManoeuvrePlan:
    """Parse a manoeuvre spec and plan its two options.

    Args:
        road: the road.
        lane: the ego lane at the start.
        spec: None or {type: lane_keeping | lane_change | obstacle_avoidance | vehicle_following, ...}
            with lane_change: at (m), to_lane (or to_offset, m from the
            reference line), length (optional, m), or a list
            changes: [{at, to_lane | to_offset, length}, ...] (e.g. a double
            lane change); obstacle_avoidance: obstacles: [{s, lane, length,
            width, offset}]; vehicle_following: the TimeGapPolicy fields
            (time_gap, standstill, a_max, d_max, j_max, k_gap, k_speed, range); and any Comfort field (a_lat, j_lat, min_length,
            margin, gap, vehicle_width, vehicle_length).
        v_design: speed used for transition lengths, m/s.
        where: location of the spec, for error messages.
    """
    spec = {"type": "lane_keeping"} if spec is None else spec
    if not isinstance(spec, Mapping) or "type" not in spec:
        raise SpecError(f"{where}: expected a mapping with a type, got {spec!r}")
    kind = spec["type"]
    own = {"lane_keeping": set(), "lane_change": {"at", "to_lane", "to_offset", "length", "changes"},
           "obstacle_avoidance": {"obstacles"}, "vehicle_following": FOLLOWING_KEYS}
    if kind not in own:
        raise SpecError(f"{where}.type: unknown manoeuvre {kind!r} (known: {', '.join(own)})")
    extra = set(spec) - own[kind] - {"type"} - set(Comfort.__dataclass_fields__)
    if extra:
        raise SpecError(f"{where}: unknown keys {sorted(extra)} for {kind}")
    comfort = comfort_from_spec(spec, where)
    lane = road.check_lane(lane)
    d_lane = road.lane_offset(lane)
    keep = Option(LateralPlan(d_lane))
    if kind == "lane_keeping":
        return ManoeuvrePlan(kind, keep, None, _neighbour(road, lane), comfort=comfort)
    if kind == "vehicle_following":
        return ManoeuvrePlan(kind, keep, None, _neighbour(road, lane), comfort=comfort,
                             following=TimeGapPolicy.from_spec(spec, where))
    if kind == "lane_change":
        changes = _lane_changes(road, d_lane, spec, v_design, comfort, where)
        ref = Option(LateralPlan(d_lane, changes))
        return ManoeuvrePlan(kind, ref, keep, road.lane_at(changes[0].d1), comfort=comfort)
    items = spec.get("obstacles")
    if not isinstance(items, Sequence) or isinstance(items, str):
        raise SpecError(f"{where}.obstacles: expected a list of obstacles")
    obstacles = tuple(_obstacle(o, road, f"{where}.obstacles[{i}]") for i, o in enumerate(items))
    ref, alt = plan_obstacles(road, lane, obstacles, v_design, comfort)
    return ManoeuvrePlan(kind, ref, alt, _neighbour(road, lane), obstacles, comfort)
