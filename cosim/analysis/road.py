"""The planner's road of a run, rebuilt from its manifest: lane lines and obstacles.

The road is the planner's: the scenario component whose class is
controllers.planning.planner's (the one playing the planner first, cosim.scenario.roles) and its `road`
parameter, rebuilt with controllers.road.builders.road_from_spec. A relative
OpenDRIVE file (`road: {opendrive: ...}`) resolves against the folder of the
scenario file the run was started from, as it did for the run. Obstacles are
the ones of its `manoeuvre` (parsed by controllers.planning.manoeuvres.plan_manoeuvre,
the planner's own parser): each a box from arc length s to s + length,
`width` wide, centred on its lane plus its offset, placed in the world with
controllers.road.builders.frenet_to_world, so on a bend the boxes and edges
follow the road exactly. Used by the figures (cosim.figures.road) and the
Foxglove outputs (cosim.foxglove).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from controllers.planning.manoeuvres import Obstacle, plan_manoeuvre
from controllers.road.builders import Road, frenet_to_world, road_from_spec
from controllers.road.opendrive import lane_borders
from cosim.analysis.rundata import RunData

PLANNER_CLASS = "controllers.planning:"
EDGE_STEP = 1.0        # m along the road between drawn points of an edge (sag 2.5 mm at R = 50 m)
OBSTACLE_STEP = 0.5    # m along an obstacle's sides


@dataclass(frozen=True)
class ScenarioRoad:
    """The planner's road and obstacles, where in the scenario they came from, its spec."""

    road: Road
    obstacles: tuple[Obstacle, ...]
    where: str
    spec: object = None


@dataclass(frozen=True)
class LaneLine:
    """One drawn line of a road: an edge (outermost) or a divider, as world points."""

    x: np.ndarray
    y: np.ndarray
    edge: bool


def planner_parameters(run: RunData) -> tuple[str, dict] | None:
    """(component name, parameters) of the run's planner with a road, or None.

    Args:
        run: the loaded run; its scenario's components are searched.
    """
    components = run.lookup("components", {}) or {}
    names = sorted(components, key=lambda n: (n != run.roles["planner"], n))
    for name in names:
        comp = components[name]
        if not isinstance(comp, dict) or not str(comp.get("python", "")).startswith(PLANNER_CLASS):
            continue
        params = comp.get("parameters") or {}
        if isinstance(params, dict) and "road" in params:
            return name, params
    return None


def _resolved(spec: object, run: RunData) -> object:
    """The road spec with a relative OpenDRIVE path made absolute (against the scenario's folder)."""
    if not isinstance(spec, dict) or not isinstance(spec.get("opendrive"), str):
        return spec
    file = Path(spec["opendrive"])
    origin = run.manifest.get("scenario_file")
    if not file.is_absolute() and origin:
        return {**spec, "opendrive": str(Path(origin).parent / file)}
    return spec


def scenario_road(run: RunData) -> ScenarioRoad | None:
    """The planner's road and obstacles; None when the run has no planner road.

    Raises:
        SpecError: the stored road or manoeuvre cannot be rebuilt (message
            names the scenario field).
    """
    found = planner_parameters(run)
    if found is None:
        return None
    name, params = found
    where = f"components.{name}.parameters"
    spec = _resolved(params["road"], run)
    road = road_from_spec(spec, f"{where}.road")
    obstacles: tuple[Obstacle, ...] = ()
    manoeuvre = params.get("manoeuvre")
    if isinstance(manoeuvre, dict) and manoeuvre.get("type") == "obstacle_avoidance":
        speed = params.get("speed") or {}
        v_design = float(speed.get("v_max", 10.0)) if isinstance(speed, dict) else 10.0
        plan = plan_manoeuvre(road, params.get("lane", 0), manoeuvre, v_design, f"{where}.manoeuvre")
        obstacles = plan.obstacles
    return ScenarioRoad(road, obstacles, where, spec)


def _stations(start: float, length: float, step: float) -> np.ndarray:
    return np.linspace(start, start + length, max(2, math.ceil(length / step) + 1))


def _offset_line(road: Road, s: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    zeros = np.zeros_like(s)
    x, y, _, _, _ = frenet_to_world(road.reference, s, np.full_like(s, d), zeros, zeros)
    return x, y


def lane_lines(found: ScenarioRoad) -> list[LaneLine]:
    """The road's lane edges and dividers, right to left.

    An OpenDRIVE road draws the file's own lane borders (every lane of the
    road over the planner's stretch, the reference line as a divider); any
    other road its `lanes` lanes of `lane_width` along its reference line.
    """
    spec = found.spec
    if isinstance(spec, dict) and "opendrive" in spec:
        borders = lane_borders(spec["opendrive"], str(spec.get("road")), float(spec.get("s_start", 0.0)),
                               spec.get("s_end"), EDGE_STEP)
        ids = [lid for lid, _, _ in borders]
        outer = {min(ids), max(ids)}
        return [LaneLine(x, y, lid in outer and lid != 0) for lid, x, y in sorted(borders)]
    road = found.road
    s = _stations(0.0, road.length, EDGE_STEP)
    right, left = road.edges()
    offsets = [right] + [(i + 0.5) * road.lane_width for i in range(road.lanes - 1)] + [left]
    return [LaneLine(*_offset_line(road, s, d), k in (0, len(offsets) - 1)) for k, d in enumerate(offsets)]


def obstacle_outline(road: Road, obstacle: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """Closed outline (x, y) of an obstacle box: right side forward, left side back.

    Args:
        road: the road the obstacle stands on.
        obstacle: its arc length, length, lane, offset and width.
    """
    s = _stations(obstacle.s, obstacle.length, OBSTACLE_STEP)
    centre = obstacle.centre(road)
    rx, ry = _offset_line(road, s, centre - 0.5 * obstacle.width)
    lx, ly = _offset_line(road, s[::-1], centre + 0.5 * obstacle.width)
    return np.concatenate([rx, lx, rx[:1]]), np.concatenate([ry, ly, ry[:1]])
