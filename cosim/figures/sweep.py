"""Histograms of a sweep's metrics: one panel per metric, over the finished samples.

Each panel shows the histogram of one metric with its p5, p50 and p95 marked
(the values of the sweep's summary), so the spread a parameter range causes is
visible at a glance next to summary.csv.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator

from cosim.figures.layouts import save_png
from cosim.figures.thin import AXIS_LIMIT

# figure edges to the panels, in inches: the top one holds the figure's title, then the
# panels' titles need TITLE_LINE_IN a line; ROW_GAP_IN holds a row's tick labels
MARGINS_IN = {"left": 0.7, "right": 0.2, "bottom": 0.4, "top": 0.55}
TITLE_LINE_IN = 0.17
ROW_GAP_IN = 0.35
COUNT_LABELS = FuncFormatter(lambda count, _: f"{count / 1000:g}k" if count >= 10_000 else f"{count:g}")
TITLE_CHARS = 36  # a title line that fits the narrowest panel (4 columns) at 9 points


def wrapped_title(name: str, width: int = TITLE_CHARS) -> str:
    """`name` in lines of at most `width` characters, broken after its dots, underscores
    and spaces (the " (n=N)" a title ends with); a part longer than a line is cut."""
    parts = re.findall(r"[^._ ]*[._ ]|[^._ ]+$", name)
    lines = [""]
    for part in parts:
        if lines[-1] and len(lines[-1]) + len(part) > width:
            lines.append("")
        lines[-1] += part
        while len(lines[-1]) > width:
            lines[-1:] = [lines[-1][:width], lines[-1][width:]]
    return "\n".join(lines)


def sweep_figure(samples: dict[str, list[float]], summary: dict[str, dict[str, float]],
                 title: str = "sweep") -> Figure:
    """One histogram panel per metric in `summary`.

    Args:
        samples: metric -> the finished samples' values.
        summary: metric -> stats (as cosim.execution.sweep.summarize returns).
        title: the figure's title.
    """
    names = [n for n in summary if samples.get(n)]
    titles = [wrapped_title(f"{name} (n={int(summary[name]['n'])})") for name in names]
    cols = min(4, max(1, len(names)))
    rows = max(1, math.ceil(len(names) / cols))
    # every panel has the same furniture (a count axis, a title of a few lines), so fixed
    # margins in inches fit any grid; the constrained layout engine took a third of the
    # drawing time (15 panels: 0.81-0.87 -> 0.50-0.58 s), most of a short `cosim sweep`
    title_in = TITLE_LINE_IN * max([t.count("\n") + 1 for t in titles] or [1])
    width, height = 4.0 * cols, (2.5 + title_in) * rows
    top_in = MARGINS_IN["top"] + title_in  # the figure's title, then the first row's
    gap_in = ROW_GAP_IN + title_in  # the tick labels of a row, then the next row's titles
    panel_in = (height - top_in - MARGINS_IN["bottom"] - (rows - 1) * gap_in) / rows
    fig = Figure(figsize=(width, height))
    fig.subplots_adjust(left=MARGINS_IN["left"] / width, right=1 - MARGINS_IN["right"] / width,
                        bottom=MARGINS_IN["bottom"] / height, top=1 - top_in / height,
                        wspace=0.4, hspace=gap_in / panel_in)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, name, panel_title in zip(axes, names, titles):
        if max(abs(v) for v in samples[name]) > AXIS_LIMIT:  # numpy cannot bin such a span
            ax.text(0.5, 0.5, f"values beyond +-{AXIS_LIMIT:g}: no histogram\n(see summary.csv)",
                    transform=ax.transAxes, ha="center", va="center", fontsize=8, color="red")
        else:
            ax.hist(samples[name], bins=min(20, max(1, len(samples[name]))), color="tab:blue",
                    alpha=0.7)
            for stat, style in (("p5", ":"), ("p50", "-"), ("p95", ":")):
                ax.axvline(summary[name][stat], color="k", ls=style, lw=1, label=stat)
        # the title names the metric (no x label to repeat it); counts of 10^4 and more
        # written 10k, so the count labels fit the fixed left margin
        ax.set_title(panel_title, fontsize=9)
        ax.set_ylabel("samples")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.yaxis.set_major_formatter(COUNT_LABELS)
    for ax in axes[len(names):]:
        ax.set_visible(False)
    if names and axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=7)
    fig.suptitle(title)
    return fig


def draw_sweep_histograms(result) -> Path:
    """Save `histograms.png` in the sweep's folder and return its path.

    Args:
        result: a cosim.execution.sweep.SweepResult.
    """
    samples = {name: [s.metrics[name] for s in result.samples
                      if s.status == "ok" and name in s.metrics and np.isfinite(s.metrics[name])]
               for name in result.summary}
    fig = sweep_figure(samples, result.summary,
                       f"sweep: {len(result.samples)} samples, {len(result.failures)} failed")
    return save_png(fig, Path(result.out_dir) / "histograms.png")
