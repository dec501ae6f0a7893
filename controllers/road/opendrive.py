"""Roads for the planner from an ASAM OpenDRIVE (.xodr) file.

    road: {opendrive: track.xodr, road: "1", lane: -1, s_start: 0, s_end: 800}

reads road `road` of the file (xml.etree, no other parser: see README,
"Dependencies, and why"), evaluates its reference line
(`controllers.road.opendrive_geometry`), shifts it by the `<laneOffset>`
records and the `<width>` polynomials of the lanes between the centre lane
and `lane` (half of that lane's own width), and samples the lane centre with
exact heading and curvature (`frenet_from_base`) into a `Path`. Right lanes
(negative ids) run along the reference line and left lanes against it (the
road's `rule="LHT"` swaps that). Over the whole road of a loop whose ends
meet, the path is closed.

The planner's `Road` (built by `controllers.road.builders.road_from_spec`)
has that lane centre as lane 0; its lanes 1, 2, ... are
the same-direction driving lanes to its left, spaced by the mean width of the
chosen lane (the planner's lane changes assume constant widths; the drawn
lane edges, `lane_borders`, are the file's own). Optional keys: `lanes`
(override that count), `closed` (true/false instead of the automatic
choice), `step` (sampling of the lane centre, m, default 0.5).

A relative `opendrive` path resolves against the current folder; the
platform rewrites it against the scenario's folder before a run.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path as FilePath

import numpy as np

from controllers.road.frenet import frenet_from_base
from controllers.road.geometry import CLOSE_TOL, Path
from controllers.road.opendrive_geometry import Geometry, PlanView
from controllers.spec import SpecError, spec_number

_GL_T, _GL_W = np.polynomial.legendre.leggauss(5)
SPEC_KEYS = {"opendrive", "road", "lane", "s_start", "s_end", "lanes", "closed", "step"}
DEFAULT_STEP = 0.5
DRIVING = "driving"


@dataclass(frozen=True)
class Cubic:
    """a + b ds + c ds^2 + d ds^3 from station `s` on (OpenDRIVE's polynomial records)."""

    s: float
    a: float
    b: float
    c: float
    d: float


def _piecewise(records: list[Cubic], s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value and first two derivatives in s of a chain of cubic records (0 before the first)."""
    out = [np.zeros_like(s) for _ in range(3)]
    if not records:
        return tuple(out)
    starts = np.array([r.s for r in records])
    idx = np.searchsorted(starts, s, side="right") - 1
    for i in np.unique(idx[idx >= 0]):
        r, m = records[i], idx == i
        u = s[m] - r.s
        out[0][m] = r.a + u * (r.b + u * (r.c + u * r.d))
        out[1][m] = r.b + u * (2 * r.c + 3 * r.d * u)
        out[2][m] = 2 * r.c + 6 * r.d * u
    return tuple(out)


@dataclass(frozen=True)
class LaneSection:
    """A `<laneSection>`: its start and, per lane id, the lane type and width records."""

    s: float
    types: dict[int, str]
    widths: dict[int, list[Cubic]]   # sOffset already added to the section start


@dataclass(frozen=True)
class OdrRoad:
    """One `<road>`: id, length, traffic rule, plan view, lane offsets and sections."""

    id: str
    length: float
    left_hand: bool
    plan: PlanView
    offsets: list[Cubic]
    sections: list[LaneSection]

    def section_index(self, s: np.ndarray) -> np.ndarray:
        starts = np.array([sec.s for sec in self.sections])
        return np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(self.sections) - 1)

    def lane_t(self, lane: int, s: np.ndarray, where: str, fraction: float = 0.5):
        """Lateral offset t (left positive) of a line in `lane` and its first two s-derivatives.

        Args:
            lane: lane id (non-zero).
            s: stations.
            fraction: 0 the lane's inner border, 0.5 its centre, 1 its outer border.
        """
        t = list(_piecewise(self.offsets, s))
        sign = 1.0 if lane > 0 else -1.0
        idx = self.section_index(s)
        for i in np.unique(idx):
            sec, m = self.sections[i], idx == i
            if lane not in sec.widths:
                raise SpecError(f"{where}: road {self.id!r} has no lane {lane} in its lane section "
                                f"at s = {sec.s:g} m (lanes: {sorted(sec.widths)})")
            step = 1 if lane > 0 else -1
            for other in range(step, lane + step, step):
                share = fraction if other == lane else 1.0
                for k, w in enumerate(_piecewise(sec.widths.get(other, []), s[m])):
                    t[k][m] += sign * share * w
        return tuple(t)


def _num(el: ET.Element, name: str, where: str, default: float | None = None) -> float:
    raw = el.get(name)
    if raw is None:
        if default is not None:
            return default
        raise SpecError(f"{where}: <{el.tag}> lacks the attribute {name!r}")
    try:
        value = float(raw)
    except ValueError:
        raise SpecError(f"{where}: <{el.tag} {name}={raw!r}> is not a number") from None
    if not math.isfinite(value):
        raise SpecError(f"{where}: <{el.tag} {name}={raw!r}> is not finite")
    return value


def _cubic(el: ET.Element, where: str, s_name: str = "s", base: float = 0.0) -> Cubic:
    return Cubic(base + _num(el, s_name, where), *(_num(el, k, where) for k in "abcd"))


def _geometry(el: ET.Element, where: str) -> Geometry:
    head = [_num(el, k, where) for k in ("s", "x", "y", "hdg", "length")]
    kinds = [c for c in el if c.tag in ("line", "arc", "spiral", "poly3", "paramPoly3")]
    if len(kinds) != 1:
        raise SpecError(f"{where}: <geometry s={head[0]:g}> needs exactly one of line, arc, "
                        f"spiral, poly3, paramPoly3, got {[c.tag for c in el]}")
    prim = kinds[0]
    names = {"line": (), "arc": ("curvature",), "spiral": ("curvStart", "curvEnd"),
             "poly3": tuple("abcd"),
             "paramPoly3": tuple(f"{c}{a}" for a in "UV" for c in "abcd")}[prim.tag]
    params = tuple(_num(prim, n, where) for n in names)
    p_range = prim.get("pRange", "normalized")
    if p_range not in ("normalized", "arcLength"):
        raise SpecError(f"{where}: paramPoly3 pRange must be normalized or arcLength, got {p_range!r}")
    return Geometry(*head, prim.tag, params, p_range == "normalized")


def _section(el: ET.Element, where: str) -> LaneSection:
    s = _num(el, "s", where)
    types, widths = {}, {}
    for lane in el.iter("lane"):
        lid = int(_num(lane, "id", where))
        types[lid] = lane.get("type", "none")
        if lid == 0:
            continue
        if lane.find("border") is not None and lane.find("width") is None:
            raise SpecError(f"{where}: lane {lid} at s = {s:g} is described by <border> records, "
                            "which are not supported (use <width>)")
        widths[lid] = sorted((_cubic(w, where, "sOffset", s) for w in lane.findall("width")),
                             key=lambda c: c.s)
    return LaneSection(s, types, widths)


def read_road(file: str | FilePath, road_id: str, where: str = "road") -> OdrRoad:
    """Road `road_id` of an OpenDRIVE file.

    Raises:
        SpecError: unreadable file, bad XML (with its line), unknown road,
            unsupported or malformed records; the message names `where`.
    """
    where_file = f"{where}.opendrive ({file})"
    try:
        root = ET.parse(file).getroot()
    except OSError as exc:
        raise SpecError(f"{where}.opendrive: cannot read {str(file)!r}: {exc.strerror or exc}") from None
    except ET.ParseError as exc:
        raise SpecError(f"{where_file}: not valid XML: {exc}") from None
    if root.tag != "OpenDRIVE":
        raise SpecError(f"{where_file}: the root element is <{root.tag}>, not <OpenDRIVE>")
    roads = {r.get("id"): r for r in root.findall("road")}
    if road_id not in roads:
        raise SpecError(f"{where}.road: no road with id {road_id!r} in {file} "
                        f"(roads: {', '.join(sorted(map(str, roads))) or 'none'})")
    el = roads[road_id]
    w = f"{where_file} road {road_id!r}"
    length = _num(el, "length", w)
    geometries = [_geometry(g, w) for g in el.iterfind("planView/geometry")]
    offsets = sorted((_cubic(o, w) for o in el.iterfind("lanes/laneOffset")), key=lambda c: c.s)
    sections = sorted((_section(s, w) for s in el.iterfind("lanes/laneSection")), key=lambda c: c.s)
    if not sections:
        raise SpecError(f"{w}: the road has no <lanes>/<laneSection>")
    return OdrRoad(road_id, length, el.get("rule", "RHT") == "LHT", PlanView(geometries, length, w),
                   offsets, sections)


def _stations(road: OdrRoad, s0: float, s1: float, step: float) -> np.ndarray:
    """Stations from s0 to s1 at most `step` apart, with every record start in between."""
    breaks = [g.s for g in road.plan.records] + [o.s for o in road.offsets]
    for sec in road.sections:
        breaks += [sec.s] + [w.s for ws in sec.widths.values() for w in ws]
    cuts = np.unique(np.clip([s0, s1, *breaks], s0, s1))
    pieces = [np.linspace(a, b, max(1, math.ceil((b - a) / step)) + 1)[:-1]
              for a, b in zip(cuts[:-1], cuts[1:])]
    return np.concatenate(pieces + [[s1]])


def _lane_knots(road: OdrRoad, lane: int, s: np.ndarray, where: str):
    """Lane-centre x, y, psi, kappa and its own arc length at stations s (along the reference)."""
    base = road.plan.evaluate(s)
    x, y, psi, kappa, _ = frenet_from_base(base, *road.lane_t(lane, s, where), s)
    # arc length of the lane centre: 5-point Gauss-Legendre of d sigma / ds per interval
    a, b = s[:-1], s[1:]
    q = (a[:, None] + 0.5 * (_GL_T + 1.0) * (b - a)[:, None]).ravel()
    *_, g = frenet_from_base(road.plan.evaluate(q), *road.lane_t(lane, q, where), q)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (b - a) * (g.reshape(-1, 5) @ _GL_W))])
    return x, y, np.unwrap(psi), kappa, sigma


def _lane_path(road: OdrRoad, lane: int, s0: float, s1: float, step: float,
               closed: bool | None, where: str) -> Path:
    s = _stations(road, s0, s1, step)
    x, y, psi, kappa, sigma = _lane_knots(road, lane, s, where)
    if (lane > 0) != road.left_hand:         # driven against the reference line
        x, y, kappa = x[::-1], y[::-1], -kappa[::-1]
        psi, sigma = psi[::-1] + np.pi, sigma[-1] - sigma[::-1]
    gap = math.hypot(x[-1] - x[0], y[-1] - y[0])
    turn = psi[-1] - psi[0]
    twists = round(turn / (2 * math.pi))
    meets = gap <= CLOSE_TOL and twists != 0 and abs(turn - 2 * math.pi * twists) <= CLOSE_TOL
    whole = s0 == 0.0 and s1 == road.length
    if closed is None:
        closed = meets and whole
    elif closed and not meets:
        raise SpecError(f"{where}.closed: the lane centre does not close: its end misses its start "
                        f"by {gap:.4f} m and {math.degrees(turn - 2 * math.pi * twists):.4f} deg")
    if closed:
        x[-1], y[-1], psi[-1] = x[0], y[0], psi[0] + 2 * math.pi * twists
    return Path(sigma, x, y, psi, kappa[:-1], kappa[1:], closed=closed)


def _same_direction_lanes(road: OdrRoad, lane: int, s0: float) -> int:
    """1 + the driving lanes next to `lane` on its left (towards the centre lane for right lanes)."""
    sec = road.sections[int(road.section_index(np.array([s0]))[0])]
    step = -1 if lane > 0 else 1      # right lanes: -3 -> -2 -> -1; left lanes: 3 -> 2 -> 1
    if road.left_hand:
        step = -step
    count, other = 1, lane + step
    while other != 0 and sec.types.get(other) == DRIVING:
        count, other = count + 1, other + step
    return count


def _spec_lane(spec: Mapping, where: str) -> int:
    lane = spec.get("lane", -1)
    if isinstance(lane, bool) or not isinstance(lane, (int, np.integer)) or lane == 0:
        raise SpecError(f"{where}.lane: expected a non-zero OpenDRIVE lane id "
                        f"(negative: right of the reference line), got {lane!r}")
    return int(lane)


def lane_from_opendrive(spec: Mapping, where: str = "road") -> tuple[Path, int, float]:
    """(lane-centre path, lane count, lane width) of {opendrive: file, road: id, lane: id, ...}.

    `controllers.road.builders.road_from_spec` makes the Road of them (module docstring).
    """
    extra = set(spec) - SPEC_KEYS
    if extra:
        raise SpecError(f"{where}: unknown keys {sorted(extra)} (known: {', '.join(sorted(SPEC_KEYS))})")
    file, road_id = spec.get("opendrive"), spec.get("road")
    if not isinstance(file, str) or not file:
        raise SpecError(f"{where}.opendrive: expected a file path, got {file!r}")
    if road_id is None or isinstance(road_id, (bool, Mapping, list)):
        raise SpecError(f"{where}.road: expected the id of a road in {file}, got {road_id!r}")
    lane = _spec_lane(spec, where)
    road = read_road(file, str(road_id), where)
    s0 = spec_number(spec.get("s_start", 0.0), f"{where}.s_start")
    s1 = spec_number(spec.get("s_end", road.length), f"{where}.s_end")
    if not 0.0 <= s0 < s1 <= road.length + 1e-9:
        raise SpecError(f"{where}: expected 0 <= s_start < s_end <= {road.length!r} (the road's "
                        f"length; leave s_end out for the whole road), got s_start = {s0!r}, "
                        f"s_end = {s1!r}")
    step = spec_number(spec.get("step", DEFAULT_STEP), f"{where}.step", positive=True)
    closed = spec.get("closed")
    if closed is not None and not isinstance(closed, bool):
        raise SpecError(f"{where}.closed: expected true or false, got {closed!r}")
    path = _lane_path(road, lane, s0, min(s1, road.length), step, closed, where)
    lanes = spec.get("lanes", _same_direction_lanes(road, lane, s0))
    if isinstance(lanes, bool) or not isinstance(lanes, int) or lanes < 1:
        raise SpecError(f"{where}.lanes: expected an integer >= 1, got {lanes!r}")
    s = _stations(road, s0, min(s1, road.length), 10.0)
    inner, _, _ = road.lane_t(lane, s, where, 0.0)
    outer, _, _ = road.lane_t(lane, s, where, 1.0)
    width = np.abs(outer - inner)
    mean = np.sum(0.5 * (width[1:] + width[:-1]) * np.diff(s)) / (s[-1] - s[0])   # trapezoid rule
    return path, lanes, float(mean)


def lane_borders(file: str | FilePath, road_id: str, s_start: float = 0.0,
                 s_end: float | None = None, step: float = 1.0) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(lane id, x, y) of the outer border of every lane of a road, and its reference line (id 0).

    Args:
        file, road_id: the OpenDRIVE file and road.
        s_start, s_end: the stretch to draw (default: the whole road).
        step: station spacing, m.
    """
    road = read_road(file, str(road_id))
    s1 = road.length if s_end is None else min(s_end, road.length)
    s = _stations(road, s_start, s1, step)
    x0, y0, psi0, *_ = road.plan.evaluate(s)
    lines = []
    ids = sorted({lid for sec in road.sections for lid in sec.widths})
    for lid in [0, *ids]:
        if lid == 0:
            t = _piecewise(road.offsets, s)[0]
        else:
            keep = np.array([lid in road.sections[i].widths for i in road.section_index(s)])
            t = np.full_like(s, np.nan)
            if keep.any():
                t[keep] = road.lane_t(lid, s[keep], "lane_borders", 1.0)[0]
        lines.append((lid, x0 - t * np.sin(psi0), y0 + t * np.cos(psi0)))
    return lines
