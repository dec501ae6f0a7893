"""Projection of a point on a trajectory window (controllers.trajectory format).

Between two window points the path is a cubic Hermite curve through both
positions with the tangents given by the headings (scaled by the arc-length
step), which matches circles and clothoids to fourth order in the point
spacing; the foot point is found on the nearest chord, then refined by Newton
iterations on that curve. Heading, curvature, speed and acceleration are
interpolated linearly in arc length; dkappa/ds is the segment's slope.

A point before the first window point or after the last one is projected on
the straight extension of the end tangent: arc length and offset follow that
line, heading, curvature, speed and acceleration hold their end values and
dkappa/ds is 0, and `extrapolated` says which end was used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.trajectory import FIELDS, TrajectoryWindow

NEWTON_ITERATIONS = 4


class WindowError(ValueError):
    """A malformed trajectory window (message names the field, index and value)."""


@dataclass(frozen=True)
class Projection:
    """Where a point falls on a window.

    Attributes:
        s: arc length of the foot point in window coordinates (< 0 or > s[-1] when extrapolated).
        x, y: foot point on the path.
        offset: signed lateral offset of the point from the path, left of the path positive.
        psi_path: path heading at the foot point (unwrapped like the window's psi).
        kappa: path curvature at the foot point (1/m, positive turning left).
        dkappa_ds: curvature gradient along the path at the foot point (1/m^2).
        v, a: reference speed and acceleration at the foot point.
        extrapolated: -1 before the window, +1 after it, 0 inside.
    """

    s: float
    x: float
    y: float
    offset: float
    psi_path: float
    kappa: float
    dkappa_ds: float
    v: float
    a: float
    extrapolated: int


def wrap_angle(angle: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def is_empty(window: TrajectoryWindow) -> bool:
    """True for an all-zero window (nothing has been planned yet)."""
    return not np.any(window.s) and not np.any(window.x) and not np.any(window.y)


def validate_window(window: TrajectoryWindow, prefix: str = "ref") -> None:
    """Raise WindowError naming `<prefix>_<field>`, index and value if the window is malformed.

    Args:
        window: the window to check.
        prefix: port prefix used in messages ("ref" or "alt").
    """
    size = len(window.s)
    if size < 2:
        raise WindowError(f"{prefix}_s: a window needs at least 2 points, got {size}")
    for name, _, _ in FIELDS:
        values = np.asarray(getattr(window, name))
        if values.shape != (size,):
            raise WindowError(f"{prefix}_{name}: expected {size} values, got shape {values.shape}")
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise WindowError(f"{prefix}_{name}[{bad[0]}] is not finite: {values[bad[0]]}")
    steps = np.diff(window.s)
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0])
        raise WindowError(f"{prefix}_s must increase strictly: {prefix}_s[{i}] = {window.s[i]}, "
                          f"{prefix}_s[{i + 1}] = {window.s[i + 1]}")


def _nearest_chord(window: TrajectoryWindow, px: float, py: float) -> tuple[int, float]:
    """Index of the nearest chord segment and the clamped chord parameter of the foot."""
    x0, y0 = window.x[:-1], window.y[:-1]
    dx, dy = np.diff(window.x), np.diff(window.y)
    length2 = np.maximum(dx * dx + dy * dy, 1e-300)
    t = np.clip(((px - x0) * dx + (py - y0) * dy) / length2, 0.0, 1.0)
    dist2 = (x0 + t * dx - px) ** 2 + (y0 + t * dy - py) ** 2
    i = int(np.argmin(dist2))
    return i, float(t[i])


def _segment(window: TrajectoryWindow, i: int) -> tuple[float, ...]:
    """End positions and end tangents (scaled by the arc-length step) of segment i as floats."""
    step = float(window.s[i + 1] - window.s[i])
    psi0, psi1 = float(window.psi[i]), float(window.psi[i + 1])
    return (float(window.x[i]), float(window.y[i]), step * math.cos(psi0), step * math.sin(psi0),
            float(window.x[i + 1]), float(window.y[i + 1]), step * math.cos(psi1), step * math.sin(psi1))


def _hermite(seg: tuple[float, ...], t: float) -> tuple[tuple[float, float], ...]:
    """Position, first and second t-derivative of the Hermite curve of a segment (scalar math)."""
    x0, y0, mx0, my0, x1, y1, mx1, my1 = seg
    t2, t3 = t * t, t * t * t
    h = (2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + t, -2 * t3 + 3 * t2, t3 - t2)
    h1 = (6 * t2 - 6 * t, 3 * t2 - 4 * t + 1, -6 * t2 + 6 * t, 3 * t2 - 2 * t)
    h2 = (12 * t - 6, 6 * t - 4, -12 * t + 6, 6 * t - 2)
    return tuple((w[0] * x0 + w[1] * mx0 + w[2] * x1 + w[3] * mx1,
                  w[0] * y0 + w[1] * my0 + w[2] * y1 + w[3] * my1) for w in (h, h1, h2))


def _refine(seg: tuple[float, ...], t: float, px: float, py: float) -> float:
    """Newton iterations for the foot parameter on the Hermite curve of a segment."""
    for _ in range(NEWTON_ITERATIONS):
        (x, y), (dx, dy), (ddx, ddy) = _hermite(seg, t)
        ex, ey = x - px, y - py
        slope = dx * dx + dy * dy + ex * ddx + ey * ddy
        if slope <= 0.0:
            break
        t = min(1.0, max(0.0, t - (ex * dx + ey * dy) / slope))
    return t


def _extrapolate(window: TrajectoryWindow, end: int, px: float, py: float) -> Projection | None:
    """Projection on the tangent line at window point `end` (0 or -1) if the point lies beyond it."""
    heading = float(window.psi[end])
    tx, ty = math.cos(heading), math.sin(heading)
    along = (px - window.x[end]) * tx + (py - window.y[end]) * ty
    if (end == 0 and along >= 0.0) or (end == -1 and along <= 0.0):
        return None
    offset = -(px - window.x[end]) * ty + (py - window.y[end]) * tx
    return Projection(s=float(window.s[end] + along), x=float(window.x[end] + along * tx),
                      y=float(window.y[end] + along * ty), offset=float(offset), psi_path=heading,
                      kappa=float(window.kappa[end]), dkappa_ds=0.0, v=float(window.v[end]),
                      a=float(window.a[end]), extrapolated=-1 if end == 0 else 1)


def project(window: TrajectoryWindow, px: float, py: float) -> Projection:
    """Project the point (px, py) on the window (assumed valid: see validate_window).

    Args:
        window: the trajectory window.
        px, py: world coordinates of the point [m].
    Returns:
        The Projection of the point (see its attributes).
    """
    i, t = _nearest_chord(window, px, py)
    last = len(window.s) - 2
    if i == 0 and t == 0.0:
        beyond = _extrapolate(window, 0, px, py)
        if beyond is not None:
            return beyond
    if i == last and t == 1.0:
        beyond = _extrapolate(window, -1, px, py)
        if beyond is not None:
            return beyond
    seg = _segment(window, i)
    t = _refine(seg, t, px, py)
    (x, y), (dx, dy), _ = _hermite(seg, t)
    norm = max(math.hypot(dx, dy), 1e-300)
    step = window.s[i + 1] - window.s[i]

    def lerp(values: np.ndarray) -> float:
        return float(values[i] + t * (values[i + 1] - values[i]))

    return Projection(s=lerp(window.s), x=x, y=y, offset=(dx * (py - y) - dy * (px - x)) / norm,
                      psi_path=lerp(window.psi), kappa=lerp(window.kappa),
                      dkappa_ds=float((window.kappa[i + 1] - window.kappa[i]) / step),
                      v=lerp(window.v), a=lerp(window.a), extrapolated=0)


def point_at(window: TrajectoryWindow, s: float) -> tuple[float, float]:
    """World position of the path at window arc length s (end tangents beyond the window).

    Args:
        window: a valid trajectory window; s: arc length in window coordinates [m].
    """
    for end, outside in ((0, s < window.s[0]), (-1, s > window.s[-1])):
        if outside:
            along = s - float(window.s[end])
            heading = float(window.psi[end])
            return (float(window.x[end]) + along * math.cos(heading),
                    float(window.y[end]) + along * math.sin(heading))
    i = min(int(np.searchsorted(window.s, s, side="right")) - 1, len(window.s) - 2)
    t = (s - float(window.s[i])) / float(window.s[i + 1] - window.s[i])
    return _hermite(_segment(window, i), t)[0]
