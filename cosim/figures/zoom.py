"""The "zoom on tracking" panel: the vehicle and planned paths around the worst |yc_cg|.

The tracking error is centimetres while the map is kilometres, so a fixed-size
zoom shows one line. The panel is an x-y map (same scale on both axes, as the
paper's Fig. 4) centred on the vehicle's CG at the tick of the largest |yc_cg|
over all the runs drawn, with a half-width of ZOOM_FACTOR times that |yc_cg|
(at least ZOOM_MIN_HALF_WIDTH), so the gap between the two paths is a quarter
of the box at most and always visible. Coordinates are relative to that point,
so the ticks read as small offsets instead of 711.02, 711.04...

The planned path is the planner's recommended window recorded at (or just
before) that tick, all its points: the map's planned path joins one point per
planner step, a chord whose sag on a tight bend is as large as the error
shown here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes

from cosim.figures import signals as sig
from cosim.analysis.rundata import RunData
from cosim.figures.thin import AXIS_LIMIT

ZOOM_FACTOR = 4.0            # half-width of the box in units of the largest |yc_cg|
ZOOM_MIN_HALF_WIDTH = 0.05   # m: a run with (almost) no error still gets a readable box


def vehicle_xy(run: RunData) -> sig.Series | None:
    """The CG's world position (the vehicle's x, y), or None if not recorded."""
    x, y = run.role_signal("vehicle", "x"), run.role_signal("vehicle", "y")
    return None if x is None or y is None else (x, y)


def worst_point(runs: Sequence[RunData]) -> tuple[int, int, float] | None:
    """Where the CG is farthest from the path over all runs: (run index, tick, |yc_cg|)
    (the geometric offset, signals.offset_cg: the zoom shows geometry).

    Ties go to the earlier run, then the earlier tick; non-finite values are
    skipped. None when no run recorded both yc and the vehicle position.

    Args:
        runs: the runs drawn, in order.
    """
    best = None
    for i, run in enumerate(runs):
        yc = sig.offset_cg(run)
        if yc is None or vehicle_xy(run) is None or len(yc[1]) == 0:
            continue
        size = np.abs(yc[1])
        size = np.where(np.isfinite(size), size, -1.0)
        k = int(np.argmax(size))
        if size[k] >= 0 and (best is None or size[k] > best[2]):
            best = (i, k, float(size[k]))
    return best


def zoom_half_width(largest_yc: float) -> float:
    """Half-width of the zoom box, m, for a largest |yc_cg| (m)."""
    return max(ZOOM_FACTOR * largest_yc, ZOOM_MIN_HALF_WIDTH)


def planned_window_at(run: RunData, t: float) -> sig.Series | None:
    """The recommended window (x, y) recorded at time t or the last one before it."""
    found = sig.window(run, "ref")
    if found is None or len(found[0].times) == 0:
        return None
    xs, ys = found
    row = max(int(np.searchsorted(xs.times, t, side="right")) - 1, 0)
    return xs.row(row), ys.row(row)


def _near(x: np.ndarray, y: np.ndarray, cx: float, cy: float, half: float) -> sig.Series:
    """The samples within twice the box around (cx, cy), relative to it.

    Only the stretch from the first to the last such sample is kept (the
    renderer need not clip a whole lap), with NaN gaps where the path leaves.
    """
    near = (np.abs(x - cx) <= 2 * half) & (np.abs(y - cy) <= 2 * half)
    inside = np.flatnonzero(near)
    if len(inside) == 0:
        return np.empty(0), np.empty(0)
    cut = slice(inside[0], inside[-1] + 1)
    keep = near[cut]
    return np.where(keep, x[cut] - cx, np.nan), np.where(keep, y[cut] - cy, np.nan)


def zoom_map(ax: Axes, runs: Sequence[RunData], colors: Sequence[str], labels: Sequence[str]) -> None:
    """Draw the zoom around the largest |yc_cg| of all runs (see the module docstring).

    Args:
        ax: the axes to draw in.
        runs: the runs, overlaid in order.
        colors: the colour of each run.
        labels: the legend label of each run's vehicle path.
    """
    worst = worst_point(runs)
    ax.set_title("zoom on tracking (largest |yc_cg|)", fontsize=10)
    ax.grid(True, alpha=0.3)
    if worst is None:
        ax.text(0.5, 0.5, "not recorded: yc, vehicle.x, vehicle.y", transform=ax.transAxes,
                ha="center", va="center", fontsize=8, color="gray")
        return
    i, k, size = worst
    t = float(runs[i].time[k])
    cx, cy = (float(v[k]) for v in vehicle_xy(runs[i]))
    half = zoom_half_width(size)
    if not (half <= AXIS_LIMIT and abs(cx) <= AXIS_LIMIT and abs(cy) <= AXIS_LIMIT):
        ax.text(0.5, 0.5, f"|yc_cg| = {size:.4g} m at x = {cx:.4g} m, y = {cy:.4g} m "
                f"(t = {t:.2f} s):\nbeyond what an axis can show",
                transform=ax.transAxes, ha="center", va="center", fontsize=8, color="red")
        return
    planned = planned_window_at(runs[i], t)
    if planned is not None:
        ax.plot(planned[0] - cx, planned[1] - cy, ":", color="k", lw=1.2,
                label=f"planned path (window at t = {runs[i].time[k]:.2f} s)")
    for j, run in enumerate(runs):
        xy = vehicle_xy(run)
        if xy is not None:
            ax.plot(*_near(xy[0], xy[1], cx, cy, half), color=colors[j], lw=1.2, label=labels[j])
    ax.plot([0.0], [0.0], "o", mfc="none", color=colors[i], ms=7,
            label=f"|yc_cg| = {100 * size:.2f} cm at t = {t:.2f} s"
            + (f" ({runs[i].label})" if len(runs) > 1 else ""))
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_xlabel(f"x - {cx:.2f} (m)")
    ax.set_ylabel(f"y - {cy:.2f} (m)")
    ax.legend(fontsize=7, loc="best")
