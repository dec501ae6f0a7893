"""The road under the map panels: lane edges, lane dividers and static obstacles.

The road is the planner's: the scenario component whose class is
controllers.planning.planner's (the one named "planner" first) and its `road`
parameter, rebuilt with controllers.road.builders.road_from_spec. Obstacles are the
ones of its `manoeuvre` (parsed by controllers.planning.manoeuvres.plan_manoeuvre, the
planner's own parser): each a box from arc length s to s + length, `width`
wide, centred on its lane plus its offset. Both are placed in the world with
controllers.road.builders.frenet_to_world, so on a bend the boxes and edges follow the
road exactly. A road that cannot be rebuilt gives a note in the panel, not a
failed figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes

from controllers.planning.manoeuvres import Obstacle, plan_manoeuvre
from controllers.road.builders import Road, frenet_to_world, road_from_spec
from controllers.spec import SpecError
from cosim.analysis.rundata import RunData

PLANNER_CLASS = "controllers.planning:"
EDGE_STEP = 1.0        # m along the road between drawn points of an edge (sag 2.5 mm at R = 50 m)
OBSTACLE_STEP = 0.5    # m along an obstacle's sides


@dataclass(frozen=True)
class ScenarioRoad:
    """The planner's road and obstacles, and where in the scenario they came from."""

    road: Road
    obstacles: tuple[Obstacle, ...]
    where: str


def planner_parameters(run: RunData) -> tuple[str, dict] | None:
    """(component name, parameters) of the run's planner with a road, or None.

    Args:
        run: the loaded run; its scenario's components are searched.
    """
    components = run.lookup("components", {}) or {}
    names = sorted(components, key=lambda n: (n != "planner", n))
    for name in names:
        comp = components[name]
        if not isinstance(comp, dict) or not str(comp.get("python", "")).startswith(PLANNER_CLASS):
            continue
        params = comp.get("parameters") or {}
        if isinstance(params, dict) and "road" in params:
            return name, params
    return None


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
    road = road_from_spec(params["road"], f"{where}.road")
    obstacles: tuple[Obstacle, ...] = ()
    manoeuvre = params.get("manoeuvre")
    if isinstance(manoeuvre, dict) and manoeuvre.get("type") == "obstacle_avoidance":
        speed = params.get("speed") or {}
        v_design = float(speed.get("v_max", 10.0)) if isinstance(speed, dict) else 10.0
        plan = plan_manoeuvre(road, params.get("lane", 0), manoeuvre, v_design, f"{where}.manoeuvre")
        obstacles = plan.obstacles
    return ScenarioRoad(road, obstacles, where)


def _stations(start: float, length: float, step: float) -> np.ndarray:
    return np.linspace(start, start + length, max(2, math.ceil(length / step) + 1))


def _offset_line(road: Road, s: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    zeros = np.zeros_like(s)
    x, y, _, _, _ = frenet_to_world(road.reference, s, np.full_like(s, d), zeros, zeros)
    return x, y


def lane_lines(road: Road) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(offset, x, y) of the road's right edge, lane dividers and left edge, in that order.

    Args:
        road: the road; lines run along its whole reference line.
    """
    s = _stations(0.0, road.length, EDGE_STEP)
    right, left = road.edges()
    offsets = [right] + [(i + 0.5) * road.lane_width for i in range(road.lanes - 1)] + [left]
    return [(d, *_offset_line(road, s, d)) for d in offsets]


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


def draw_road(ax: Axes, run: RunData) -> None:
    """Lane edges (solid grey), dividers (dashed grey) and obstacles (filled boxes) of a run.

    Args:
        ax: the map axes.
        run: the run whose scenario holds the planner's road.
    """
    try:
        found = scenario_road(run)
    except SpecError as exc:
        ax.text(0.01, 0.01, f"road not drawn: {exc}", transform=ax.transAxes,
                fontsize=7, color="gray", va="bottom")
        return
    if found is None:
        return
    lines = lane_lines(found.road)
    for k, (_, x, y) in enumerate(lines):
        edge = k in (0, len(lines) - 1)
        ax.plot(x, y, "-" if edge else "--", color="gray", lw=0.8 if edge else 0.6,
                label="lane edge" if k == 0 else ("lane divider" if k == 1 and not edge else None))
    for k, obstacle in enumerate(found.obstacles):
        ax.fill(*obstacle_outline(found.road, obstacle), color="dimgray", alpha=0.85,
                label="obstacle" if k == 0 else None)
