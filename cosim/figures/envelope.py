"""Decimation of long time series for plotting, keeping every peak exactly.

A panel is a few hundred pixels wide, a track run records 27,500 ticks per
signal: drawing every tick costs time and shows nothing more. `envelope` cuts
the samples into `buckets` consecutive groups of (nearly) equal size and keeps,
of each group, its first, last, smallest and largest sample (the M4 scheme), in
their original order. A line through those points covers, within each group,
exactly the vertical span of the full line, and it starts and ends where the
full line does; with groups narrower than a pixel column the picture is the
same. The points kept are original samples (x and y unchanged, no averaging),
so every group's minimum and maximum are plotted exactly.
"""

from __future__ import annotations

import numpy as np

BUCKETS = 1024          # groups per line: above any panel's width in pixels (about 450-700 here)


def bucket_edges(n: int, buckets: int) -> np.ndarray:
    """Start indices of `buckets` consecutive groups covering range(n), plus n at the end.

    Args:
        n: number of samples.
        buckets: number of groups (1 <= buckets <= n).
    """
    return (np.arange(buckets + 1) * n) // buckets


def envelope_indices(y: np.ndarray, buckets: int = BUCKETS) -> np.ndarray:
    """Sorted indices of the samples `envelope` keeps (all of them for short lines).

    Args:
        y: the values, 1-D.
        buckets: number of groups.
    """
    n = y.size
    if n < 4 * buckets or not np.all(np.isfinite(y)):
        return np.arange(n)     # short, or with gaps (NaN) the plot must show as gaps
    edges = bucket_edges(n, buckets)
    starts, ends = edges[:-1], edges[1:]
    width = int(np.max(ends - starts))
    # Pad every group to the same width with its own last sample so one
    # vectorised argmin/argmax covers all groups.
    offsets = np.minimum(starts[:, None] + np.arange(width)[None, :], (ends - 1)[:, None])
    block = y[offsets]
    lows = offsets[np.arange(buckets), np.argmin(block, axis=1)]
    highs = offsets[np.arange(buckets), np.argmax(block, axis=1)]
    return np.unique(np.concatenate([starts, ends - 1, lows, highs]))


def envelope(x: np.ndarray, y: np.ndarray, buckets: int = BUCKETS) -> tuple[np.ndarray, np.ndarray]:
    """The samples of (x, y) a line plot needs: per group first, last, min and max.

    Args:
        x: abscissae (time), 1-D, same length as y.
        y: values, 1-D.
        buckets: number of groups; lines shorter than 4 * buckets come back whole.

    Returns:
        (x, y) restricted to the kept samples, in their original order.
    """
    x, y = np.asarray(x), np.asarray(y)
    if x.shape != y.shape or y.ndim != 1:
        raise ValueError(f"envelope: x and y must be 1-D of one length, got {x.shape} and {y.shape}")
    keep = envelope_indices(y, buckets)
    if keep.size == y.size:
        return x, y
    return x[keep], y[keep]
