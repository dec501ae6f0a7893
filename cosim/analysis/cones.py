"""Cone hits: which cones the vehicle body touched during a run.

The body is a rectangle in the ground plane, `length` x `width`, aligned with
the vehicle's heading psi. Its position along the body axis is given by
`front`, the distance from the CG forward to the front bumper (by default
length / 2: the CG at the rectangle's centre). A cone is a point; it is hit
when it lies inside or on the rectangle at any recorded tick. Each cone counts
once however many ticks it stays inside.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def cones_inside(x: float, y: float, psi: float, cones: np.ndarray,
                 length: float, width: float, front: float | None = None) -> np.ndarray:
    """Which cones lie inside the body rectangle of one vehicle pose.

    Args:
        x, y: CG position, world frame (m).
        psi: heading (rad, counter-clockwise from world x).
        cones: (n, 2) cone positions (m).
        length, width: body size (m).
        front: CG-to-front-bumper distance (m); None: length / 2.

    Returns:
        Boolean array (n,).
    """
    return _inside(np.array([x]), np.array([y]), np.array([psi]), cones,
                   length, width, front)[0]


def _inside(x: np.ndarray, y: np.ndarray, psi: np.ndarray, cones: np.ndarray,
            length: float, width: float, front: float | None) -> np.ndarray:
    """(ticks, cones) boolean: cone j inside the body at tick i."""
    front = length / 2.0 if front is None else front
    rear = length - front
    dx = cones[None, :, 0] - x[:, None]
    dy = cones[None, :, 1] - y[:, None]
    c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
    lon = c * dx + s * dy
    lat = -s * dx + c * dy
    return (lon <= front) & (lon >= -rear) & (np.abs(lat) <= width / 2.0)


def cone_hits(x: np.ndarray, y: np.ndarray, psi: np.ndarray, cones: Sequence[Sequence[float]],
              length: float = 4.5, width: float = 1.8, front: float | None = None,
              chunk: int = 4096) -> np.ndarray:
    """For each cone, whether the body touched it at any tick.

    Args:
        x, y, psi: vehicle CG trajectory and heading, one value per tick.
        cones: cone positions [[x, y], ...] (m).
        length, width: body size (m), defaults 4.5 x 1.8.
        front: CG-to-front-bumper distance (m); None: length / 2.
        chunk: ticks processed at once (bounds memory on long runs).

    Returns:
        Boolean array, one entry per cone.
    """
    cones_arr = np.asarray(cones, dtype=float).reshape(-1, 2)
    hit = np.zeros(len(cones_arr), dtype=bool)
    for start in range(0, len(x), chunk):
        sl = slice(start, start + chunk)
        hit |= _inside(x[sl], y[sl], psi[sl], cones_arr, length, width, front).any(axis=0)
    return hit
