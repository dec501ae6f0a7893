"""Roads: a reference line with lanes, road (Frenet) coordinates, and track builders.

Lane numbering: lane 0 is the reference line itself (the driving lane of
right-hand traffic) and lane i lies i lane widths to its left, so the
reference line's geometry is exactly the path driven in lane 0. A point is
described in road coordinates by the reference arc length s and a lateral
offset d (left positive); `frenet_to_world` (controllers.road.frenet, re-exported
here) turns an offset profile d(s) into a world trajectory with exact heading,
curvature and arc-length rate.

Builders give the paper's roads; `road_from_spec` reads the YAML form:
    road: satory_standin
    road: {builder: two_lane, length: 600, radius: 200}
    road: {reference: {segments: [...]}, lanes: 2, lane_width: 3.5}
    road: {opendrive: track.xodr, road: "1", lane: -1}    # controllers.road.opendrive
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from controllers.road.frenet import frenet_from_base, frenet_to_world  # noqa: F401 (re-exported)
from controllers.road.geometry import Path, SpecError, spec_number
from controllers.road.opendrive import lane_from_opendrive
from controllers.spec import MAX_LANES, MAX_LENGTH, MAX_REACH


@dataclass(frozen=True)
class Road:
    """A reference line (centre of lane 0) with `lanes` lanes of `lane_width` to its left."""

    reference: Path
    lanes: int = 2
    lane_width: float = 3.5
    _centres: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        if isinstance(self.lanes, bool) or not isinstance(self.lanes, int) \
                or not 1 <= self.lanes <= MAX_LANES:
            raise SpecError(f"road.lanes: expected an integer 1..{MAX_LANES}, got {self.lanes!r}")
        spec_number(self.lane_width, "road.lane_width", positive=True, at_most=MAX_REACH)

    @property
    def length(self) -> float:
        """Length of the reference line, m."""
        return self.reference.length

    @property
    def closed(self) -> bool:
        """True for a loop."""
        return self.reference.closed

    def check_lane(self, lane, where: str = "lane") -> int:
        """Validate a lane index and return it as an int."""
        if isinstance(lane, bool) or not isinstance(lane, (int, np.integer)) or not 0 <= lane < self.lanes:
            raise SpecError(f"{where}: expected a lane index 0..{self.lanes - 1}, got {lane!r}")
        return int(lane)

    def lane_offset(self, lane: int) -> float:
        """Lateral offset of a lane centre from the reference line, m."""
        return self.check_lane(lane) * self.lane_width

    def lane_at(self, d: float) -> int:
        """Index of the lane whose centre is nearest to lateral offset d (clamped to the road)."""
        return int(np.clip(np.rint(d / self.lane_width), 0, self.lanes - 1))

    def lane_centre(self, lane: int) -> Path:
        """The centre line of a lane as a path of its own (cached)."""
        lane = self.check_lane(lane)
        if lane not in self._centres:
            self._centres[lane] = self.reference.offset(lane * self.lane_width)
        return self._centres[lane]

    def edges(self) -> tuple[float, float]:
        """Lateral offsets of the right and left road edges, m."""
        return -0.5 * self.lane_width, (self.lanes - 0.5) * self.lane_width


def _turn(radius: float, angle_deg: float, transition: float) -> list[tuple[float, float, float]]:
    """Clothoid in, arc, clothoid out: a turn of angle_deg (signed) at radius, as pieces."""
    k = np.sign(angle_deg) / radius
    arc = radius * abs(np.radians(angle_deg)) - transition
    if arc <= 0:
        raise SpecError(f"turn of {angle_deg} deg at radius {radius} m too short for "
                        f"{transition} m clothoids")
    return [(transition, 0.0, k), (arc, k, k), (transition, k, 0.0)]


# One half of the stand-in loop: (straight, radius, angle_deg, clothoid length) ...
# The turns add up to exactly 180 deg, so the second half, the same pieces
# again, is the first one rotated by 180 deg about the midpoint of the two
# ends and the loop closes exactly.
_SATORY_HALF = (
    (380.0, 150.0, 90.0, 40.0),
    (240.0, 300.0, -35.0, 30.0),
    (90.0, 500.0, 35.0, 30.0),
    (130.0, 50.0, 90.0, 25.0),
)


def satory_standin(lane_width: float = 3.5, lanes: int = 2) -> Road:
    """A ~3.5 km closed test track standing in for Versailles-Satory.

    The real track geometry is not published (the paper only plots a logged
    curvature), so this loop only matches its character: long straights,
    turns of radius 50 to 500 m, an S-bend, and clothoid transitions (so the
    curvature is continuous). It is point-symmetric and closes exactly;
    counter-clockwise, starting at the origin heading east.

    Args:
        lane_width: lane width, m.
        lanes: number of lanes (lane 0 is the loop itself).
    """
    pieces = []
    for straight, radius, angle, clothoid in _SATORY_HALF * 2:
        pieces.append((straight, 0.0, 0.0))
        pieces.extend(_turn(radius, angle, clothoid))
    return Road(Path.from_pieces(pieces, closed=True), lanes=lanes, lane_width=lane_width)


def two_lane_road(length: float = 600.0, radius: float | None = None, lane_width: float = 3.5,
                  lanes: int = 2, transition: float = 40.0) -> Road:
    """A two-lane road starting at the origin heading east: straight or with one bend.

    Args:
        length: total length, m (at most MAX_LENGTH).
        radius: None (left out) for a straight road; otherwise the signed radius
            (left positive, never 0) of a bend in the middle half, entered and
            left through clothoids of `transition` m, with straights of
            length/4 either side.
        lane_width, lanes: lane layout.
        transition: clothoid length of the bend, m.
    """
    length = spec_number(length, "road.length", positive=True, at_most=MAX_LENGTH)
    if radius is None:
        return Road(Path.from_pieces([(length, 0.0, 0.0)]), lanes=lanes, lane_width=lane_width)
    radius = spec_number(radius, "road.radius")
    if radius == 0:
        raise SpecError("road.radius: must not be 0 (leave radius out for a straight road; "
                        "a negative radius bends right)")
    transition = spec_number(transition, "road.transition", positive=True, at_most=MAX_LENGTH)
    k = 1.0 / radius
    arc = length / 2 - 2 * transition
    if arc <= 0:
        raise SpecError(f"road.length: {length} m too short for a bend with {transition} m clothoids")
    pieces = [(length / 4, 0.0, 0.0), (transition, 0.0, k), (arc, k, k), (transition, k, 0.0),
              (length / 4, 0.0, 0.0)]
    return Road(Path.from_pieces(pieces), lanes=lanes, lane_width=lane_width)


BUILDERS = {"satory_standin": satory_standin, "two_lane": two_lane_road}


# the roads built in this process, by their spec as canonical JSON: a Road only holds
# its geometry (and lane centres made from it on demand), so the planners of a sweep's
# samples on one worker share one; a road read from an OpenDRIVE file is built each time
ROADS_KEPT = 8
_roads: dict[str, Road] = {}


def road_from_spec(spec, where: str = "road") -> Road:
    """A Road from its YAML form (see the module docstring).

    Args:
        spec: a builder name, {builder: name, **its keyword arguments},
            {reference: <path spec>, lanes: n, lane_width: w}, or
            {opendrive: file, road: id, lane: id, ...} (controllers.road.opendrive).
        where: location of the spec, for error messages.
    """
    key = canonical_key(spec, spec)
    road = _roads.get(key) if key is not None else None
    if road is None:
        road = _build_road(spec, where)
        if key is not None:
            keep(_roads, key, road, ROADS_KEPT)
    return road


def keep(store: dict, key, value, limit: int) -> None:
    """store[key] = value, for what a process keeps by content; the oldest entry goes at `limit`."""
    if len(store) >= limit:
        store.pop(next(iter(store)))
    store[key] = value


def canonical_key(value, road) -> str | None:
    """`value` as canonical JSON (floats exactly, 1 and 1.0 apart), a key for what is kept per
    process; None, keep nothing, when `road` (a road spec) is read from an OpenDRIVE file (its
    content may change between runs) or JSON cannot write `value`."""
    if isinstance(road, Mapping) and "opendrive" in road:
        return None
    try:
        return json.dumps(value, sort_keys=True, allow_nan=True)
    except (TypeError, ValueError):
        return None


def _build_road(spec, where: str) -> Road:
    """road_from_spec without the kept roads."""
    if isinstance(spec, str):
        spec = {"builder": spec}
    if not isinstance(spec, Mapping):
        raise SpecError(f"{where}: expected a builder name or a mapping, got {spec!r}")
    if "builder" in spec:
        name = spec["builder"]
        if name not in BUILDERS:
            raise SpecError(f"{where}.builder: unknown road {name!r} (known: {', '.join(BUILDERS)})")
        kwargs = {k: v for k, v in spec.items() if k != "builder"}
        try:
            return BUILDERS[name](**kwargs)
        except TypeError as exc:
            raise SpecError(f"{where}: bad parameters for {name}: {exc}") from None
        except SpecError as exc:  # a builder's field messages say "road.<field>" already
            raise exc if str(exc).startswith(where) else SpecError(f"{where}: {exc}") from None
    if "opendrive" in spec:
        path, lanes, width = lane_from_opendrive(spec, where)
        return Road(path, lanes=lanes, lane_width=width)
    extra = set(spec) - {"reference", "lanes", "lane_width"}
    if "reference" not in spec or extra:
        raise SpecError(f"{where}: expected keys reference, lanes, lane_width, got {sorted(spec)}")
    lanes = spec.get("lanes", 2)
    if isinstance(lanes, bool) or not isinstance(lanes, int) or not 1 <= lanes <= MAX_LANES:
        raise SpecError(f"{where}.lanes: expected an integer 1..{MAX_LANES}, got {lanes!r}")
    width = spec_number(spec.get("lane_width", 3.5), f"{where}.lane_width", positive=True,
                        at_most=MAX_REACH)
    return Road(Path.from_spec(spec["reference"], f"{where}.reference"), lanes=lanes, lane_width=width)
