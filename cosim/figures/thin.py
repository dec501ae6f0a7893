"""Thinning a long drawn path to what the pixels can show.

A long run's vehicle path has hundreds of thousands of points, several per
pixel of the track map; matplotlib keeps and transforms every one of them, so
the figure's memory grew with the run's duration. `thin_path` keeps the points
at least a quarter of a pixel apart along the path (arc length), plus the
first and the last: the line drawn deviates from the full one by less than a
quarter of a pixel, which antialiasing does not show.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

PIXEL_FRACTION = 0.25  # kept points at least this many pixels apart along the path
DPI = 110  # the resolution the PNGs are rendered at (cosim.figures.layouts.save_png)
# the largest |value| an axis shows (cosim.figures.layouts.clip_huge_axes): beyond it the
# span, margins or ticks matplotlib computes to lay the axis out can overflow a float
AXIS_LIMIT = 1e300


def pixel_size(ax: Axes, x: np.ndarray, y: np.ndarray, dpi: float) -> float:
    """A lower bound of the data length one pixel of `ax` covers when it shows all of (x, y).

    Args:
        ax: the axes the path goes into (its size before layout: the layout only shrinks it,
            so the bound holds).
        x, y: the path.
        dpi: the resolution the figure is rendered at.
    """
    if len(x) == 0:
        return 0.0
    width_in, height_in = ax.figure.get_size_inches() * ax.get_position().size
    span_x, span_y = float(np.ptp(x)), float(np.ptp(y))
    return max(span_x / (width_in * dpi), span_y / (height_in * dpi))


def thin_path(x: np.ndarray, y: np.ndarray, spacing: float,
              block: int = 1 << 15) -> tuple[np.ndarray, np.ndarray]:
    """The points of the polyline (x, y) at least `spacing` apart along it, first and last kept.

    Args:
        x, y: the path's points.
        spacing: the data length between kept points (0 or less: every point kept).
        block: points measured at a time (the work arrays' size, whatever the path's length).
    """
    if spacing <= 0 or len(x) < 3:
        return x, y
    kept, along, last_bin = [np.zeros(1, dtype=np.intp)], 0.0, 0.0
    for start in range(1, len(x), block):
        stop = min(start + block, len(x))
        step = np.hypot(x[start:stop] - x[start - 1:stop - 1], y[start:stop] - y[start - 1:stop - 1])
        np.cumsum(step, out=step)
        step += along
        along = float(step[-1])
        bins = np.floor_divide(step, spacing, out=step)
        new_bin = np.flatnonzero(np.diff(bins, prepend=last_bin))  # the first point of each new bin
        last_bin = float(bins[-1])
        kept.append(new_bin + start)
    keep = np.concatenate(kept)
    if keep[-1] != len(x) - 1:
        keep = np.append(keep, len(x) - 1)
    return x[keep], y[keep]
