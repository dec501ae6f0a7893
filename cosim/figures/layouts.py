"""Paper-style figures of a run (or several runs overlaid), saved as PNG.

Four layouts after the paper, for vehicle runs, and one for any run:
- "track" (Fig. 4): twelve panels, 4 x 3: x-y map at equal aspect with the
  planned path (and the planner's road: lane edges, obstacles;
  cosim.figures.road), curvature rho, speed tracking vx vs vx_ref, speed
  error ex, the side-wind and aero forces, steering angle delta, yL, psiL,
  yc (the paper's yL - ls psiL) with yc_cg (the CG's geometric offset), zoom
  on tracking (a box sized from the largest |yc_cg| of all runs;
  cosim.figures.zoom), mu_hat beside the true mu.
- "manoeuvre" (Fig. 5/6): the map across the top at equal aspect with the
  planner's recommended and alternative windows, then curvature, yL, psiL,
  yc with yc_cg, steering angle (with an inset around the manoeuvre start),
  speed tracking, speed error and the reference acceleration force m·a_ref.
- "speed" (Fig. 4.3 and 4.4): one column per run, speed tracking above its
  speed error ex and the aero force: `cosim compare RUN_NO_AERO RUN_AERO
  --layout speed` gives the paper's two panels side by side.
- "following" (vehicle following, cosim.figures.following): nine panels: map
  with both vehicles, gap, both speeds, time gap and TTC, acceleration,
  steering, the follower's lateral errors yc, yL, psiL.
- "signals" (cosim.figures.signal_plot): recorded signals against time, one
  panel each, with their units; the chosen ones (`cosim plot RUN --signals
  'ball.*'`), else the run's first 24.

The layout comes from the scenario's `metrics.figures` when given; else a run
where no component plays the vehicle, controller or planner (cosim.scenario.roles)
means signals; else a run with a lead vehicle (the planner's lead_x input connected) means following;
else a scenario name with "lane", "obstacle",
"iso3888" or "manoeuvre" in it means manoeuvre, one with "satory", "track"
or "friction" means track; else a planner that moved off its lane
(its `lateral_offset` not always 0) means manoeuvre; else track. (The
planner always offers an alternative lane, so alternative windows alone say
nothing.)
Figures are built on matplotlib's Agg backend without pyplot, so drawing
touches no global state. Time series are drawn through their min/max envelope
(cosim.figures.envelope: every peak kept exactly, a few thousand points per
line instead of one per tick), and one Agg draw both lays out and renders.
An axis whose data reach beyond +-1e300 (values near the largest float, which
matplotlib cannot lay out) is clipped to that range, with a note in its panel.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from cosim.figures import fidelity_panels as fp
from cosim.figures import panels as pan
from cosim.figures.thin import AXIS_LIMIT, DPI
from cosim.figures.following import following_figure
from cosim.figures import signals as sig
from cosim.figures.signal_plot import default_signals, select_signals, signals_figure
from cosim.analysis.metrics import lead_component
from cosim.analysis.outputs import check_output_file, output_file, write_failure
from cosim.analysis.rundata import AnalysisError, RunData, loaded_run

LAYOUTS = ("track", "manoeuvre", "speed", "following", "signals")
MANOEUVRE_WORDS = ("lane", "obstacle", "iso3888", "manoeuvre", "maneuver")
TRACK_WORDS = ("satory", "track", "friction")
PNG_COMPRESS_LEVEL = 1   # zlib level: same pixels, ~15 % larger file, encodes about twice as fast


def choose_layout(run: RunData) -> str:
    """"track", "manoeuvre", "following" or "signals" for this run (rules in the module docstring).

    Raises:
        AnalysisError: the scenario's `metrics.figures` is not a known layout.
    """
    hint = run.lookup("metrics.figures")
    if hint is not None:
        if hint not in LAYOUTS:
            raise AnalysisError(f"{run.run_dir / 'manifest.json'}: scenario.metrics.figures: "
                                f"expected one of {', '.join(LAYOUTS)}, found {hint!r}")
        return hint
    if not run.vehicle_run:
        return "signals"
    if lead_component(run) is not None:
        return "following"
    name = str(run.lookup("name", "")).lower()
    if any(word in name for word in MANOEUVRE_WORDS):
        return "manoeuvre"
    if any(word in name for word in TRACK_WORDS):
        return "track"
    offset = run.role_signal("planner", "lateral_offset")
    if offset is not None and np.any(offset != 0):
        return "manoeuvre"
    return "track"


def _errors(axes, runs: Sequence[RunData]) -> None:
    pan.time_series(axes[0], runs, lambda r: sig.role_series(r, "controller", "yL"), "yL",
                    "lateral error at preview point", "yL (m)")
    pan.time_series(axes[1], runs, lambda r: sig.role_series(r, "controller", "psiL"), "psiL",
                    "heading error", "psiL (rad)")
    fp.lateral_cg_panel(axes[2], runs)


def _speed(ax, runs: Sequence[RunData]) -> None:
    pan.tracking(ax, runs, lambda r: sig.role_series(r, "vehicle", "vx"), sig.speed_reference,
                 ("vx", "vx_ref"), "speed tracking", "speed (m/s)")


def _curvature(ax, runs: Sequence[RunData]) -> None:
    pan.time_series(ax, runs, sig.curvature, "rho", "path curvature", "rho (1/m)")


def track_figure(runs: Sequence[RunData]) -> Figure:
    """The Fig. 4 layout (twelve panels) for the given runs, overlaid."""
    fig = Figure(figsize=(15, 16), layout="constrained")
    axes = fig.subplots(4, 3).ravel()
    pan.trajectory_map(axes[0], runs)
    _curvature(axes[1], runs)
    fp.forces_panel(axes[2], runs)
    _speed(axes[3], runs)
    fp.speed_error_panel(axes[4], runs)
    fp.steering_panel(axes[5], runs)
    _errors(axes[6:9], runs)
    pan.zoom_map(axes[9], runs)
    pan.friction(axes[10], runs)
    axes[11].set_axis_off()
    fig.suptitle(_title(runs, "track run"))
    return fig


def speed_figure(runs: Sequence[RunData]) -> Figure:
    """Fig. 4.3/4.4: per run a column of speed tracking, speed error and aero force."""
    fig = Figure(figsize=(6 * len(runs), 10), layout="constrained")
    axes = np.asarray(fig.subplots(3, len(runs), squeeze=False))
    for k, run in enumerate(runs):
        _speed(axes[0, k], [run])
        axes[0, k].set_title(f"speed tracking: {run.label}", fontsize=10)
        fp.speed_error_panel(axes[1, k], [run])
        fp.forces_panel(axes[2, k], [run])
    fig.suptitle(_title(runs, "speed tracking"))
    return fig


def manoeuvre_figure(runs: Sequence[RunData]) -> Figure:
    """The Fig. 5/6 layout (map across the top, six panels below) for the given runs."""
    fig = Figure(figsize=(14, 18), layout="constrained")
    grid = fig.add_gridspec(5, 2)
    top = fig.add_subplot(grid[0, :])
    pan.trajectory_map(top, runs, both_windows=True,
                       title="road and planned trajectories", equal=False)
    fp.focus_on_manoeuvre(top, runs[0])
    cells = [fig.add_subplot(grid[r, c]) for r in range(1, 5) for c in range(2)]
    _curvature(cells[0], runs)
    _errors(cells[1:4], runs)
    fp.steering_panel(cells[4], runs)
    _speed(cells[5], runs)
    fp.speed_error_panel(cells[6], runs)
    pan.acceleration_force(cells[7], runs)
    fig.suptitle(_title(runs, "manoeuvre"))
    return fig


def _title(runs: Sequence[RunData], kind: str) -> str:
    if len(runs) > 1:
        return f"{kind}: " + ", ".join(r.label for r in runs)
    return f"{kind}: {runs[0].lookup('name', runs[0].label)} ({runs[0].label})"


def build_figure(runs: Sequence[RunData], layout: str | None = None,
                 signals: Sequence[str] = ()) -> tuple[Figure, str]:
    """The figure of one or several runs, and the layout used.

    Args:
        runs: loaded runs (at least one); overlaid in order.
        layout: one of LAYOUTS, or None to choose from the first run.
        signals: glob patterns of signals to draw against time (the "signals"
            layout, whatever `layout` says); empty: the layout's own signals.
    Raises:
        AnalysisError: an unknown layout, or a pattern that matches no recorded signal.
    """
    # values near the largest float overflow in the panels' arithmetic: the axes are then
    # clipped (clip_huge_axes), numpy's warnings would only be noise
    with np.errstate(over="ignore", invalid="ignore"):
        return _build_figure(runs, layout, signals)


def _build_figure(runs: Sequence[RunData], layout: str | None,
                  signals: Sequence[str]) -> tuple[Figure, str]:
    if not runs:
        raise AnalysisError("no run to draw")
    if signals:
        names = select_signals(runs[0], signals)
        return signals_figure(runs, names, _title(runs, "signals")), "signals"
    layout = layout or choose_layout(runs[0])
    if layout not in LAYOUTS:
        raise AnalysisError(f"layout: expected one of {', '.join(LAYOUTS)}, found {layout!r}")
    if layout == "signals":
        names, note = default_signals(runs[0])
        return signals_figure(runs, names, _title(runs, "signals") + (f"\n{note}" if note else "")), layout
    if layout == "following":
        return following_figure(runs, _title(runs, "vehicle following")), layout
    builders = {"track": track_figure, "manoeuvre": manoeuvre_figure, "speed": speed_figure}
    fig = builders[layout](runs)
    return fig, layout


def clip_huge_axes(fig: Figure) -> list[str]:
    """Limit every axis whose data reach beyond +-AXIS_LIMIT to that range, noted in its panel.

    Matplotlib lays an axis out from its data limits: with values near the largest
    float (1.8e308) their span, the margins or the ticks overflow and the drawing fails.
    The lines stay whole; what lies beyond the limit is cut at the panel's edge.

    Args:
        fig: the figure, built and not yet drawn.
    Returns:
        The titles of the panels clipped ("" for a panel without one).
    """
    clipped = []
    for ax in fig.axes:
        box, axes_clipped = ax.dataLim, []
        for name, (low, high), set_limits in (("x", box.intervalx, ax.set_xlim),
                                               ("y", box.intervaly, ax.set_ylim)):
            if not (np.isfinite(low) and np.isfinite(high) and low <= high):
                continue  # no data on this axis
            if max(abs(low), abs(high)) <= AXIS_LIMIT:
                continue
            low, high = (float(np.clip(v, -AXIS_LIMIT, AXIS_LIMIT)) for v in (low, high))
            if low == high:  # all beyond the same side: the axis from 0 to the limit
                low, high = min(low, 0.0), max(high, 0.0)
            # no autoscaling first, nor an equal aspect met by moving the limits: either
            # would lay the axis out from the data, overflowing
            getattr(ax, f"set_autoscale{name}_on")(False)
            ax.set_adjustable("box")
            set_limits(low, high)
            axes_clipped.append(name)
        if axes_clipped:
            ax.text(0.01, 0.99, f"{' and '.join(axes_clipped)} beyond +-{AXIS_LIMIT:g} not shown",
                    transform=ax.transAxes, ha="left", va="top", fontsize=7, color="red")
            clipped.append(ax.get_title())
    return clipped


def save_png(fig: Figure, path: Path) -> Path:
    """Render a figure with Agg into `path` (PNG) and return the path.

    One draw does the constrained layout and the rendering; `savefig` would
    first run a whole extra draw (with rendering disabled) only to lay out.
    The pixels are the same as `savefig(path, dpi=DPI)` gives. No software
    or time stamp in the file, so the bytes depend on the figure only.

    Args:
        fig: the figure (built on the Agg canvas, without pyplot).
        path: the PNG file to write (its folder exists).
    Raises:
        UserError: the file cannot be written (no permission, a folder of that name).
    """
    fig.set_dpi(DPI)
    canvas = FigureCanvasAgg(fig)
    with np.errstate(over="ignore", invalid="ignore"):
        clip_huge_axes(fig)
        canvas.draw()
    image = Image.fromarray(np.asarray(canvas.buffer_rgba()))
    try:
        image.save(path, format="png", compress_level=PNG_COMPRESS_LEVEL, dpi=(DPI, DPI))
    except OSError as exc:
        raise write_failure(path, exc) from None
    return path


def draw_figures(run_dir: str | Path, layout: str | None = None,
                 run: RunData | None = None, signals: Sequence[str] = (),
                 out: str | Path | None = None) -> list[Path]:
    """Draw the figure of a run (paper-style for a vehicle run) into its folder.

    Args:
        run_dir: the run folder; the PNG is written there as `figure_<layout>.png`.
        layout: one of LAYOUTS, or None to choose from the scenario.
        run: `run_dir` already loaded (`load_run`), so a caller that also writes
            the metrics parses signals.csv once; None loads it here.
        signals: glob patterns of signals to draw against time instead (see build_figure).
        out: the PNG file to write instead of the run folder's (its folder is created
            if missing).

    Returns:
        The PNG files written.
    """
    run = loaded_run(run_dir, run)
    if out is not None:
        check_output_file(out)
    fig, layout = build_figure([run], layout, signals)
    return [save_png(fig, output_file(out) if out is not None else Path(run_dir) / f"figure_{layout}.png")]
