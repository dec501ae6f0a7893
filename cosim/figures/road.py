"""The road under the map panels: lane edges, lane dividers and static obstacles.

The road, its lines and its obstacles are rebuilt from the run's manifest by
cosim.analysis.road (the planner's own road builder; an OpenDRIVE road draws
the file's lane borders). A road that cannot be rebuilt gives a note in the
panel, not a failed figure.
"""

from __future__ import annotations

from matplotlib.axes import Axes

from controllers.spec import SpecError
from cosim.analysis.road import lane_lines, obstacle_outline, scenario_road
from cosim.analysis.rundata import RunData


def draw_road(ax: Axes, run: RunData) -> None:
    """Lane edges (solid grey), dividers (dashed grey) and obstacles (filled boxes) of a run.

    Args:
        ax: the map axes.
        run: the run whose scenario holds the planner's road.
    """
    try:
        found = scenario_road(run)
        lines = lane_lines(found) if found is not None else []
    except SpecError as exc:
        ax.text(0.01, 0.01, f"road not drawn: {exc}", transform=ax.transAxes,
                fontsize=7, color="gray", va="bottom")
        return
    if found is None:
        return
    labelled = set()
    for line in lines:
        label = "lane edge" if line.edge else "lane divider"
        ax.plot(line.x, line.y, "-" if line.edge else "--", color="gray", lw=0.8 if line.edge else 0.6,
                label=None if label in labelled else label)
        labelled.add(label)
    for k, obstacle in enumerate(found.obstacles):
        ax.fill(*obstacle_outline(found.road, obstacle), color="dimgray", alpha=0.85,
                label="obstacle" if k == 0 else None)
