"""Histograms of a sweep's metrics: one panel per metric, over the finished samples.

Each panel shows the histogram of one metric with its p5, p50 and p95 marked
(the values of the sweep's summary), so the spread a parameter range causes is
visible at a glance next to summary.csv.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from cosim.figures.layouts import save_png

MARGINS_IN = {"left": 0.7, "right": 0.2, "bottom": 0.55, "top": 0.65}  # figure edges to the panels


def sweep_figure(samples: dict[str, list[float]], summary: dict[str, dict[str, float]],
                 title: str = "sweep") -> Figure:
    """One histogram panel per metric in `summary`.

    Args:
        samples: metric -> the finished samples' values.
        summary: metric -> stats (as cosim.execution.sweep.summarize returns).
        title: the figure's title.
    """
    names = [n for n in summary if samples.get(n)]
    cols = min(4, max(1, len(names)))
    rows = max(1, math.ceil(len(names) / cols))
    width, height = 4.0 * cols, 3.0 * rows
    fig = Figure(figsize=(width, height))
    # every panel has the same furniture (a count axis, a title, a label), so fixed margins in
    # inches fit any grid; the constrained layout engine took a third of the drawing time
    # (15 panels: 0.81-0.87 -> 0.50-0.58 s), most of a short `cosim sweep` after its runs
    fig.subplots_adjust(left=MARGINS_IN["left"] / width, right=1 - MARGINS_IN["right"] / width,
                        bottom=MARGINS_IN["bottom"] / height, top=1 - MARGINS_IN["top"] / height,
                        wspace=0.4, hspace=0.7)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, name in zip(axes, names):
        ax.hist(samples[name], bins=min(20, max(1, len(samples[name]))), color="tab:blue",
                alpha=0.7)
        for stat, style in (("p5", ":"), ("p50", "-"), ("p95", ":")):
            ax.axvline(summary[name][stat], color="k", ls=style, lw=1, label=stat)
        ax.set_title(f"{name} (n={int(summary[name]['n'])})", fontsize=9)
        ax.set_xlabel(name)
        ax.set_ylabel("samples")
    for ax in axes[len(names):]:
        ax.set_visible(False)
    if names:
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
