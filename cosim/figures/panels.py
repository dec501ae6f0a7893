"""The panels of the paper-style figures, each drawn for one or several runs.

Every panel function takes a matplotlib Axes and a list of runs and overlays
the runs in order (colour i for run i), so one code path draws a single run's
figure and a comparison of runs. A panel whose signal a run did not record
shows a note in the axes instead of failing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from matplotlib.axes import Axes

from cosim.figures import signals as sig
from cosim.figures import zoom
from cosim.figures.envelope import envelope
from cosim.figures.road import draw_road
from cosim.figures.thin import DPI, PIXEL_FRACTION, pixel_size, thin_path
from cosim.analysis.metrics import run_cone_hits
from cosim.analysis.rundata import RunData

COLORS = ("tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange", "tab:brown",
          "tab:pink", "tab:gray", "tab:olive", "tab:cyan")
Getter = Callable[[RunData], "sig.Series | None"]


def color(i: int) -> str:
    """The colour of run number i."""
    return COLORS[i % len(COLORS)]


def _label(runs: Sequence[RunData], i: int, what: str) -> str:
    return what if len(runs) == 1 else f"{runs[i].label}: {what}"


def series_line(ax: Axes, x: np.ndarray, y: np.ndarray, *style: str, scale: float = 1.0,
                **props) -> None:
    """Plot y (times scale) against time, decimated by `envelope` (peaks kept exactly).

    Args:
        ax: the axes to draw in.
        x, y: time and values, 1-D, one length.
        style: optional format string ("--").
        scale: factor applied to the kept values (e.g. a mass for a force).
        props: Line2D properties (color, lw, label).
    """
    xs, ys = envelope(x, y)
    ax.plot(xs, ys if scale == 1.0 else scale * ys, *style, **props)


def _missing(ax: Axes, what: str) -> None:
    ax.text(0.5, 0.5, f"not recorded: {what}", transform=ax.transAxes,
            ha="center", va="center", fontsize=8, color="gray")


def _finish(ax: Axes, title: str, xlabel: str, ylabel: str) -> None:
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")


def time_series(ax: Axes, runs: Sequence[RunData], getter: Getter, what: str,
                title: str, ylabel: str, scale: float = 1.0) -> None:
    """One signal against time for every run.

    Args:
        ax: the axes to draw in.
        runs: the runs, overlaid in order.
        getter: run -> (time, values) or None.
        what: the signal's name, for legends and the missing note.
        title, ylabel: panel title and y-axis label (with unit).
        scale: factor applied to the values (e.g. a mass for a force).
    """
    drawn = False
    for i, run in enumerate(runs):
        found = getter(run)
        if found is not None:
            series_line(ax, found[0], found[1], scale=scale, color=color(i), lw=1.0,
                        label=_label(runs, i, what))
            drawn = True
    if not drawn:
        _missing(ax, what)
    _finish(ax, title, "time (s)", ylabel)


def tracking(ax: Axes, runs: Sequence[RunData], actual: Getter, reference: Getter,
             names: tuple[str, str], title: str, ylabel: str) -> None:
    """A signal and its reference (dashed) against time for every run."""
    drawn = False
    for i, run in enumerate(runs):
        for getter, name, style in ((actual, names[0], "-"), (reference, names[1], "--")):
            found = getter(run)
            if found is not None:
                series_line(ax, found[0], found[1], style, color=color(i), lw=1.0,
                            label=_label(runs, i, name))
                drawn = True
    if not drawn:
        _missing(ax, f"{names[0]}, {names[1]}")
    _finish(ax, title, "time (s)", ylabel)


def _windows(ax: Axes, run: RunData, prefix: str, style: dict, label: str, count: int) -> None:
    """Draw `count` of the run's recorded windows, evenly spread in time."""
    found = sig.window(run, prefix)
    if found is None:
        return
    xs, ys = found
    rows = np.unique(np.linspace(0, len(xs.times) - 1, count).round().astype(int))
    for k, row in enumerate(rows):
        ax.plot(xs.row(row), ys.row(row), lw=0.8, alpha=0.6,
                label=label if k == 0 else None, **style)


def _cones(ax: Axes, run: RunData) -> None:
    """The scenario's cones: hit ones as red crosses, the others as orange triangles."""
    found = run_cone_hits(run)
    if found is None:
        return
    cones, hit = found
    ax.plot(cones[~hit, 0], cones[~hit, 1], "^", color="tab:orange", ms=5, ls="none", label="cone")
    if hit.any():
        ax.plot(cones[hit, 0], cones[hit, 1], "x", color="red", ms=7, mew=2, ls="none",
                label=f"cone hit ({int(hit.sum())})")


def trajectory_map(ax: Axes, runs: Sequence[RunData], both_windows: bool = False,
                   title: str = "trajectory (x-y map)", equal: bool = True) -> None:
    """Road (cosim.figures.road), vehicle CG path and planned path; planner windows too if asked.

    Args:
        ax: the axes to draw in.
        runs: the runs, overlaid in order.
        both_windows: draw sampled recommended (ref) and alternative (alt) windows.
        title: the panel title.
        equal: same scale on both axes (off for long straight manoeuvres).
    """
    draw_road(ax, runs[0])
    drawn = False
    for i, run in enumerate(runs):
        path = sig.path_trace(run, "ref")
        if path is not None:
            ax.plot(path[0], path[1], ":", color="k", lw=1.0, label=_label(runs, i, "planned path"))
        if both_windows:
            _windows(ax, run, "ref", {"color": "tab:green"}, _label(runs, i, "recommended"), 6)
            _windows(ax, run, "alt", {"color": "tab:orange", "ls": "--"},
                     _label(runs, i, "alternative"), 6)
        xy = zoom.vehicle_xy(run)
        if xy is not None:
            spacing = PIXEL_FRACTION * pixel_size(ax, xy[0], xy[1], DPI)
            xs, ys = thin_path(xy[0], xy[1], spacing)
            ax.plot(xs, ys, color=color(i), lw=1.2, label=_label(runs, i, "vehicle"))
            drawn = True
    _cones(ax, runs[0])
    if not drawn:
        _missing(ax, ", ".join(runs[0].role_column("vehicle", s) for s in ("x", "y")))
    if equal:
        ax.set_aspect("equal", adjustable="datalim")
    _finish(ax, title, "x (m)", "y (m)")


def zoom_map(ax: Axes, runs: Sequence[RunData]) -> None:
    """The vehicle and planned paths around the largest |yc_cg| of all runs (cosim.figures.zoom)."""
    zoom.zoom_map(ax, runs, [color(i) for i in range(len(runs))],
                  [_label(runs, i, "vehicle") for i in range(len(runs))])


def friction(ax: Axes, runs: Sequence[RunData]) -> None:
    """Friction estimate mu_hat against the true friction (dashed)."""
    tracking(ax, runs, lambda r: sig.role_series(r, "controller", "mu_hat"),
             lambda r: sig.friction(r)[0], ("mu_hat", "mu (true)"),
             "friction estimate", "mu (-)")


def acceleration_force(ax: Axes, runs: Sequence[RunData]) -> None:
    """Reference acceleration force m * a_ref (m: controller's nominal mass)."""
    drawn = False
    for i, run in enumerate(runs):
        found = sig.reference_acceleration(run)
        if found is not None:
            series_line(ax, found[0], found[1], scale=sig.vehicle_mass(run), color=color(i),
                        lw=1.0, label=_label(runs, i, "m·a_ref"))
            drawn = True
    if not drawn:
        _missing(ax, "a_ref (controller or planner.ref_a)")
    _finish(ax, "reference acceleration force", "time (s)",
            "reference acceleration force m·a_ref (N)")
