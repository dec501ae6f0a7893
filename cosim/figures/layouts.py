"""Paper-style figures of a run (or several runs overlaid), saved as PNG.

Two layouts, after the paper:
- "track" (Fig. 4): nine panels, 3 x 3: x-y map with the planned path (and
  the planner's road: lane edges, obstacles; cosim.figures.road),
  curvature rho, speed tracking vx vs vx_ref, yL, psiL, yc, zoom on tracking
  (a box sized from the largest |yc| of all runs; cosim.figures.zoom),
  mu_hat vs true mu, steering angle delta.
- "manoeuvre" (Fig. 5/6): seven panels: the map across the top with the
  planner's recommended and alternative windows, then curvature, yL, psiL,
  steering angle, speed tracking and the reference acceleration force m·a_ref.
- "following" (vehicle following, cosim.figures.following): nine panels: map
  with both vehicles, gap, both speeds, time gap and TTC, acceleration,
  steering, the follower's lateral errors yc, yL, psiL.

The layout comes from the scenario's `metrics.figures` when given; else a run
with a lead vehicle (the planner's lead_x input connected) means following;
else a scenario name with "lane", "obstacle",
"iso3888" or "manoeuvre" in it means manoeuvre, one with "satory", "track"
or "friction" means track; else a planner that moved off its lane
(`planner.lateral_offset` not always 0) means manoeuvre; else track. (The
planner always offers an alternative lane, so alternative windows alone say
nothing.)
Figures are built on matplotlib's Agg backend without pyplot, so drawing
touches no global state. Time series are drawn through their min/max envelope
(cosim.figures.envelope: every peak kept exactly, a few thousand points per
line instead of one per tick), and one Agg draw both lays out and renders.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from cosim.figures import panels as pan
from cosim.figures.following import following_figure
from cosim.figures import signals as sig
from cosim.analysis.metrics import lead_component
from cosim.analysis.rundata import AnalysisError, RunData, loaded_run

LAYOUTS = ("track", "manoeuvre", "following")
MANOEUVRE_WORDS = ("lane", "obstacle", "iso3888", "manoeuvre", "maneuver")
TRACK_WORDS = ("satory", "track", "friction")
DPI = 110
PNG_COMPRESS_LEVEL = 1   # zlib level: same pixels, ~15 % larger file, encodes about twice as fast


def choose_layout(run: RunData) -> str:
    """"track", "manoeuvre" or "following" for this run (rules in the module docstring).

    Raises:
        AnalysisError: the scenario's `metrics.figures` is not a known layout.
    """
    hint = run.lookup("metrics.figures")
    if hint is not None:
        if hint not in LAYOUTS:
            raise AnalysisError(f"{run.run_dir / 'manifest.json'}: scenario.metrics.figures: "
                                f"expected one of {', '.join(LAYOUTS)}, found {hint!r}")
        return hint
    if lead_component(run) is not None:
        return "following"
    name = str(run.lookup("name", "")).lower()
    if any(word in name for word in MANOEUVRE_WORDS):
        return "manoeuvre"
    if any(word in name for word in TRACK_WORDS):
        return "track"
    offset = run.signal("planner.lateral_offset")
    if offset is not None and np.any(offset != 0):
        return "manoeuvre"
    return "track"


def _delta(ax, runs: Sequence[RunData]) -> None:
    pan.time_series(ax, runs, lambda r: sig.column(r, "controller.delta"), "delta",
                    "steering angle", "delta (rad)")


def _errors(axes, runs: Sequence[RunData], with_yc: bool) -> None:
    pan.time_series(axes[0], runs, lambda r: sig.column(r, "controller.yL"), "yL",
                    "lateral error at preview point", "yL (m)")
    pan.time_series(axes[1], runs, lambda r: sig.column(r, "controller.psiL"), "psiL",
                    "heading error", "psiL (rad)")
    if with_yc:
        pan.time_series(axes[2], runs, sig.lateral_cg, "yc", "lateral error at CG", "yc (m)")


def _speed(ax, runs: Sequence[RunData]) -> None:
    pan.tracking(ax, runs, lambda r: sig.column(r, "vehicle.vx"), sig.speed_reference,
                 ("vx", "vx_ref"), "speed tracking", "speed (m/s)")


def _curvature(ax, runs: Sequence[RunData]) -> None:
    pan.time_series(ax, runs, sig.curvature, "rho", "path curvature", "rho (1/m)")


def track_figure(runs: Sequence[RunData]) -> Figure:
    """The Fig. 4 layout (nine panels) for the given runs, overlaid."""
    fig = Figure(figsize=(15, 12), layout="constrained")
    axes = fig.subplots(3, 3).ravel()
    pan.trajectory_map(axes[0], runs)
    _curvature(axes[1], runs)
    _speed(axes[2], runs)
    _errors(axes[3:6], runs, with_yc=True)
    pan.zoom_map(axes[6], runs)
    pan.friction(axes[7], runs)
    _delta(axes[8], runs)
    fig.suptitle(_title(runs, "track run"))
    return fig


def manoeuvre_figure(runs: Sequence[RunData]) -> Figure:
    """The Fig. 5/6 layout (map across the top, six panels below) for the given runs."""
    fig = Figure(figsize=(14, 15), layout="constrained")
    grid = fig.add_gridspec(4, 2)
    pan.trajectory_map(fig.add_subplot(grid[0, :]), runs, both_windows=True,
                       title="road and planned trajectories", equal=False)
    cells = [fig.add_subplot(grid[r, c]) for r in range(1, 4) for c in range(2)]
    _curvature(cells[0], runs)
    _errors(cells[1:3], runs, with_yc=False)
    _delta(cells[3], runs)
    _speed(cells[4], runs)
    pan.acceleration_force(cells[5], runs)
    fig.suptitle(_title(runs, "manoeuvre"))
    return fig


def _title(runs: Sequence[RunData], kind: str) -> str:
    if len(runs) > 1:
        return f"{kind}: " + ", ".join(r.label for r in runs)
    return f"{kind}: {runs[0].lookup('name', runs[0].label)} ({runs[0].label})"


def build_figure(runs: Sequence[RunData], layout: str | None = None) -> tuple[Figure, str]:
    """The figure of one or several runs, and the layout used.

    Args:
        runs: loaded runs (at least one); overlaid in order.
        layout: one of LAYOUTS, or None to choose from the first run.
    """
    if not runs:
        raise AnalysisError("no run to draw")
    layout = layout or choose_layout(runs[0])
    if layout not in LAYOUTS:
        raise AnalysisError(f"layout: expected one of {', '.join(LAYOUTS)}, found {layout!r}")
    if layout == "following":
        return following_figure(runs, _title(runs, "vehicle following")), layout
    fig = track_figure(runs) if layout == "track" else manoeuvre_figure(runs)
    return fig, layout


def save_png(fig: Figure, path: Path) -> Path:
    """Render a figure with Agg into `path` (PNG) and return the path.

    One draw does the constrained layout and the rendering; `savefig` would
    first run a whole extra draw (with rendering disabled) only to lay out.
    The pixels are the same as `savefig(path, dpi=DPI)` gives. No software
    or time stamp in the file, so the bytes depend on the figure only.

    Args:
        fig: the figure (built on the Agg canvas, without pyplot).
        path: the PNG file to write.
    """
    fig.set_dpi(DPI)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    image = Image.fromarray(np.asarray(canvas.buffer_rgba()))
    image.save(path, format="png", compress_level=PNG_COMPRESS_LEVEL, dpi=(DPI, DPI))
    return path


def draw_figures(run_dir: str | Path, layout: str | None = None,
                 run: RunData | None = None) -> list[Path]:
    """Draw the paper-style figure of a run into its folder.

    Args:
        run_dir: the run folder; the PNG is written there as `figure_<layout>.png`.
        layout: "track", "manoeuvre" or None to choose from the scenario.
        run: `run_dir` already loaded (`load_run`), so a caller that also writes
            the metrics parses signals.csv once; None loads it here.

    Returns:
        The PNG files written.
    """
    run = loaded_run(run_dir, run)
    fig, layout = build_figure([run], layout)
    return [save_png(fig, Path(run_dir) / f"figure_{layout}.png")]
