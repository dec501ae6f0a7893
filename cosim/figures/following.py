"""The vehicle-following figure: gap, both speeds and the follower's lateral errors.

Chosen by cosim.figures.layouts for a run whose planner follows a lead
vehicle (the planner's lead_x connected; the lead is the component feeding it, see
cosim.analysis.metrics.lead_component). Nine panels, 3 x 3: the map (road,
both vehicles' paths, equal aspect), the gap against the desired gap, the
speeds of follower and lead with the follower's reference; the time gap and
time to collision, the policy's acceleration reference against the
follower's ax, the follower's steering angle; its lateral errors yc, yL and psiL.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from cosim.figures import panels as pan
from cosim.figures import signals as sig
from cosim.analysis.metrics import TIME_GAP_MIN_SPEED, lead_component
from cosim.analysis.rundata import RunData

TTC_SHOWN = 20.0     # s: the time-to-collision axis stops here (it is infinite while opening)


def _label(runs: Sequence[RunData], i: int, what: str) -> str:
    return what if len(runs) == 1 else f"{runs[i].label}: {what}"


def _lead_column(run: RunData, signal: str) -> sig.Series | None:
    lead = lead_component(run)
    return None if lead is None else sig.column(run, f"{lead}.{signal}")


def _map(ax: Axes, runs: Sequence[RunData]) -> None:
    pan.trajectory_map(ax, runs, title="road, follower and lead")
    for i, run in enumerate(runs):
        x, y = _lead_column(run, "x"), _lead_column(run, "y")
        if x is not None and y is not None:      # wide and pale: the follower's path runs inside it
            ax.plot(x[1], y[1], color=pan.color(i), lw=4.0, alpha=0.3, label=_label(runs, i, "lead"))
            ax.plot(x[1][-1], y[1][-1], "s", color=pan.color(i), ms=5, label=_label(runs, i, "lead at the end"))
    ax.legend(fontsize=7, loc="best")


def _speeds(ax: Axes, runs: Sequence[RunData]) -> None:
    pan.tracking(ax, runs, lambda r: sig.role_series(r, "vehicle", "vx"), sig.speed_reference,
                 ("follower vx", "follower vx_ref"), "speeds", "speed (m/s)")
    for i, run in enumerate(runs):
        found = _lead_column(run, "vx")
        if found is not None:
            pan.series_line(ax, found[0], found[1], ":", color=pan.color(i), lw=1.5,
                            label=_label(runs, i, "lead vx"))
    ax.legend(fontsize=7, loc="best")


def _ratio(run: RunData, kind: str) -> sig.Series | None:
    """Time gap (gap / vx, moving) or time to collision (gap / closing speed, closing)."""
    gap, vx = run.role_signal("planner", "gap"), run.role_signal("vehicle", "vx")
    v_lead = _lead_column(run, "vx")
    if gap is None or vx is None or v_lead is None:
        return None
    speed = vx if kind == "time gap" else vx - v_lead[1]
    floor = TIME_GAP_MIN_SPEED if kind == "time gap" else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        values = np.where(speed > floor, np.maximum(gap, 0.0) / speed, np.nan)
    return run.time, np.minimum(values, TTC_SHOWN)


def _headways(ax: Axes, runs: Sequence[RunData]) -> None:
    pan.tracking(ax, runs, lambda r: _ratio(r, "time gap"), lambda r: _ratio(r, "ttc"),
                 ("time gap", "time to collision"), f"time gap and TTC (capped at {TTC_SHOWN:g} s)",
                 "time (s)")


def following_figure(runs: Sequence[RunData], title: str) -> Figure:
    """The following layout (nine panels, 3 x 3) for the given runs, overlaid."""
    fig = Figure(figsize=(15, 12), layout="constrained")
    axes = fig.subplots(3, 3).ravel()
    _map(axes[0], runs)
    pan.tracking(axes[1], runs, lambda r: sig.role_series(r, "planner", "gap"),
                 lambda r: sig.role_series(r, "planner", "gap_ref"), ("gap", "desired gap"),
                 "gap to the lead (bumper to bumper, along the road)", "gap (m)")
    _speeds(axes[2], runs)
    _headways(axes[3], runs)
    pan.tracking(axes[4], runs, lambda r: sig.role_series(r, "vehicle", "ax"),
                 lambda r: sig.role_series(r, "planner", "a_follow"), ("follower ax", "policy a_ref"),
                 "longitudinal acceleration", "acceleration (m/s2)")
    pan.time_series(axes[5], runs, lambda r: sig.role_series(r, "controller", "delta"), "delta",
                    "follower: steering angle", "delta (rad)")
    pan.time_series(axes[6], runs, sig.lateral_cg, "yc", "follower: lateral error at CG", "yc (m)")
    pan.time_series(axes[7], runs, lambda r: sig.role_series(r, "controller", "yL"), "yL",
                    "follower: lateral error at preview point", "yL (m)")
    pan.time_series(axes[8], runs, lambda r: sig.role_series(r, "controller", "psiL"), "psiL",
                    "follower: heading error", "psiL (rad)")
    fig.suptitle(title)
    return fig
