"""Panels the paper's Fig. 4 and 6 show beyond the basic ones: speed error, the
aero and side-wind forces, both lateral errors at the CG, and the steering
around the start of a manoeuvre (where a law may steer the wrong way first).

Same conventions as cosim.figures.panels: one Axes, a list of runs overlaid
in order, a note in the axes for what a run did not record.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes

from cosim.figures import panels as pan
from cosim.figures import signals as sig
from cosim.analysis.metrics import speed_error
from cosim.analysis.rundata import RunData

#: seconds shown before and after the manoeuvre start in the steering inset
INSET_BEFORE, INSET_AFTER = 1.5, 2.0


def speed_error_panel(ax: Axes, runs: Sequence[RunData]) -> None:
    """ex = vx - vx_ref (the paper's Fig. 4.3/4.4 show the speed; the error is what differs)."""
    def getter(run):
        ex = speed_error(run)
        return None if ex is None else (run.time, ex)
    pan.time_series(ax, runs, getter, "ex", "speed error", "ex = vx - vx_ref (m/s)")


def aero_force(run: RunData) -> sig.Series | None:
    """The aero drag Fwx = -cx vx |vx| the plant applies (cx: the vehicle's parameter, else 0.42)."""
    vx = run.role_signal("vehicle", "vx")
    if vx is None:
        return None
    cx = run.number(run.role_path("vehicle", "parameters.cx"), 0.42)
    return run.time, -cx * vx * np.abs(vx)


def side_wind(run: RunData) -> sig.Series | None:
    """The side-wind force fed to the vehicle's wind_fy, when connected."""
    src = run.source_of(run.role_column("vehicle", "wind_fy")) if run.roles["vehicle"] else None
    return None if src is None else (run.time, run.columns[src])


def forces_panel(ax: Axes, runs: Sequence[RunData]) -> None:
    """Side-wind force Fwy (solid) and aero drag Fwx (dashed) on the vehicle."""
    drawn = False
    for i, run in enumerate(runs):
        for getter, name, style in ((side_wind, "Fwy (side wind)", "-"),
                                    (aero_force, "Fwx (aero drag)", "--")):
            found = getter(run)
            if found is not None:
                pan.series_line(ax, found[0], found[1], style, color=pan.color(i), lw=1.0,
                                label=pan._label(runs, i, name))
                drawn = True
    if not drawn:
        pan._missing(ax, ", ".join(runs[0].role_column("vehicle", s) for s in ("vx", "wind_fy")))
    pan._finish(ax, "external forces", "time (s)", "force (N)")


def lateral_cg_panel(ax: Axes, runs: Sequence[RunData]) -> None:
    """yc = yL - ls psiL (the paper's, solid) and yc_cg, the CG's geometric offset (dashed)."""
    pan.tracking(ax, runs, sig.lateral_cg, lambda r: sig.role_series(r, "controller", "yc_cg"),
                 ("yc", "yc_cg"), "lateral error at CG",
                 "yc = yL - ls psiL, yc_cg geometric (m)")


def manoeuvre_start(run: RunData) -> float | None:
    """Time the planner's manoeuvre_state first leaves 0, or None."""
    state = run.role_signal("planner", "manoeuvre_state")
    if state is None or not np.any(state > 0):
        return None
    return float(run.time[int(np.flatnonzero(state > 0)[0])])


def steering_panel(ax: Axes, runs: Sequence[RunData]) -> None:
    """Steering angle; with a manoeuvre, its start marked and an inset around it
    (the counter-steer, if any, shows there: the steer leaving 0 the wrong way)."""
    pan.time_series(ax, runs, lambda r: sig.role_series(r, "controller", "delta"), "delta",
                    "steering angle", "delta (rad)")
    start = manoeuvre_start(runs[0])
    if start is None:
        return
    inset = ax.inset_axes([0.06, 0.55, 0.38, 0.4])
    lo, hi = start - INSET_BEFORE, start + INSET_AFTER
    for i, run in enumerate(runs):
        delta = run.role_signal("controller", "delta")
        if delta is None:
            continue
        keep = (run.time >= lo) & (run.time <= hi)
        inset.plot(run.time[keep], delta[keep], color=pan.color(i), lw=1.0)
    for axes in (ax, inset):
        axes.axvline(start, color="gray", ls=":", lw=0.8)
    inset.axhline(0.0, color="k", lw=0.5)
    inset.set_title("manoeuvre start", fontsize=7)
    inset.tick_params(labelsize=6)


def focus_on_manoeuvre(ax: Axes, run: RunData, margin: float = 30.0) -> None:
    """Equal aspect on the stretch of road where the manoeuvre happens.

    A 600 m road is 7 m wide: at equal aspect over its whole length a lane
    change is invisible, so the x range is the vehicle's from `margin` m
    before the manoeuvre starts to `margin` m after it ends (planner's
    manoeuvre_state back to 0, else the run's end); without a manoeuvre, the
    whole map at equal aspect.
    """
    state = run.role_signal("planner", "manoeuvre_state")
    x, y = run.role_signal("vehicle", "x"), run.role_signal("vehicle", "y")
    if state is None or x is None or y is None or not np.any(state > 0):
        ax.set_aspect("equal", adjustable="datalim")
        return
    k0 = int(np.flatnonzero(state > 0)[0])
    after = np.flatnonzero(state[k0:] == 0)
    k1 = k0 + int(after[0]) if after.size else len(x) - 1
    lo, hi = min(x[k0], x[k1]) - margin, max(x[k0], x[k1]) + margin
    keep = (x >= lo) & (x <= hi)
    ax.set_xlim(lo, hi)
    ax.set_ylim(float(np.min(y[keep])) - 4.0, float(np.max(y[keep])) + 4.0)
    ax.set_aspect("equal", adjustable="box")
