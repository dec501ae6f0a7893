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

import bisect
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
        if not np.isfinite(values).all():
            i = int(np.flatnonzero(~np.isfinite(values))[0])
            raise WindowError(f"{prefix}_{name}[{i}] is not finite: {values[i]}")
    if not (window.s[1:] > window.s[:-1]).all():
        i = int(np.flatnonzero(window.s[1:] <= window.s[:-1])[0])
        raise WindowError(f"{prefix}_s must increase strictly: {prefix}_s[{i}] = {window.s[i]}, "
                          f"{prefix}_s[{i + 1}] = {window.s[i + 1]}")


class PreparedWindow:
    """A window with its chords precomputed and its fields as Python lists (fast scalar access).

    Args:
        window: a valid trajectory window.
    """

    def __init__(self, window: TrajectoryWindow) -> None:
        self.x0, self.y0 = window.x[:-1], window.y[:-1]
        self.dx, self.dy = np.diff(window.x), np.diff(window.y)
        self.length2 = np.maximum(self.dx * self.dx + self.dy * self.dy, 1e-300)
        self.x, self.y, self.psi = window.x.tolist(), window.y.tolist(), window.psi.tolist()
        self.kappa, self.s = window.kappa.tolist(), window.s.tolist()
        self.v, self.a = window.v.tolist(), window.a.tolist()

    def nearest_chord(self, px: float, py: float) -> tuple[int, float]:
        """Index of the nearest chord segment and the clamped chord parameter of the foot."""
        t = np.clip(((px - self.x0) * self.dx + (py - self.y0) * self.dy) / self.length2, 0.0, 1.0)
        dist2 = (self.x0 + t * self.dx - px) ** 2 + (self.y0 + t * self.dy - py) ** 2
        i = int(np.argmin(dist2))
        return i, float(t[i])

    def segment(self, i: int) -> tuple[float, ...]:
        """End positions and end tangents (scaled by the arc-length step) of segment i."""
        step = self.s[i + 1] - self.s[i]
        psi0, psi1 = self.psi[i], self.psi[i + 1]
        return (self.x[i], self.y[i], step * math.cos(psi0), step * math.sin(psi0),
                self.x[i + 1], self.y[i + 1], step * math.cos(psi1), step * math.sin(psi1))


def _hermite(seg: tuple[float, ...], t: float, order: int = 2) -> list[tuple[float, float]]:
    """Position and t-derivatives up to `order` of the Hermite curve of a segment (scalar math)."""
    x0, y0, mx0, my0, x1, y1, mx1, my1 = seg
    t2, t3 = t * t, t * t * t
    weights = ((2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + t, -2 * t3 + 3 * t2, t3 - t2),
               (6 * t2 - 6 * t, 3 * t2 - 4 * t + 1, -6 * t2 + 6 * t, 3 * t2 - 2 * t),
               (12 * t - 6, 6 * t - 4, -12 * t + 6, 6 * t - 2))
    return [(w[0] * x0 + w[1] * mx0 + w[2] * x1 + w[3] * mx1,
             w[0] * y0 + w[1] * my0 + w[2] * y1 + w[3] * my1) for w in weights[:order + 1]]


def _refine(seg: tuple[float, ...], t: float, px: float, py: float) -> float:
    """Newton iterations for the foot parameter on the Hermite curve of a segment."""
    for _ in range(NEWTON_ITERATIONS):
        (x, y), (dx, dy), (ddx, ddy) = _hermite(seg, t)
        ex, ey = x - px, y - py
        slope = dx * dx + dy * dy + ex * ddx + ey * ddy
        if slope <= 0.0:
            break
        new_t = min(1.0, max(0.0, t - (ex * dx + ey * dy) / slope))
        if abs(new_t - t) < 1e-13:
            return new_t
        t = new_t
    return t


def _extrapolate(w: PreparedWindow, end: int, px: float, py: float) -> Projection | None:
    """Projection on the tangent line at window point `end` (0 or -1) if the point lies beyond it."""
    heading = w.psi[end]
    tx, ty = math.cos(heading), math.sin(heading)
    along = (px - w.x[end]) * tx + (py - w.y[end]) * ty
    if (end == 0 and along >= 0.0) or (end == -1 and along <= 0.0):
        return None
    offset = -(px - w.x[end]) * ty + (py - w.y[end]) * tx
    return Projection(s=w.s[end] + along, x=w.x[end] + along * tx, y=w.y[end] + along * ty,
                      offset=offset, psi_path=heading, kappa=w.kappa[end], dkappa_ds=0.0,
                      v=w.v[end], a=w.a[end], extrapolated=-1 if end == 0 else 1)


def project(window: TrajectoryWindow | PreparedWindow, px: float, py: float) -> Projection:
    """Project the point (px, py) on the window (assumed valid: see validate_window).

    Args:
        window: the trajectory window, or a PreparedWindow of it (faster for several points).
        px, py: world coordinates of the point [m].
    Returns:
        The Projection of the point (see its attributes).
    """
    w = window if isinstance(window, PreparedWindow) else PreparedWindow(window)
    i, t = w.nearest_chord(px, py)
    last = len(w.s) - 2
    for end, at_end in ((0, i == 0 and t == 0.0), (-1, i == last and t == 1.0)):
        beyond = _extrapolate(w, end, px, py) if at_end else None
        if beyond is not None:
            return beyond
    seg = w.segment(i)
    t = _refine(seg, t, px, py)
    (x, y), (dx, dy) = _hermite(seg, t, order=1)
    norm = max(math.hypot(dx, dy), 1e-300)

    def lerp(values: list[float]) -> float:
        return values[i] + t * (values[i + 1] - values[i])

    return Projection(s=lerp(w.s), x=x, y=y, offset=(dx * (py - y) - dy * (px - x)) / norm,
                      psi_path=lerp(w.psi), kappa=lerp(w.kappa),
                      dkappa_ds=(w.kappa[i + 1] - w.kappa[i]) / (w.s[i + 1] - w.s[i]),
                      v=lerp(w.v), a=lerp(w.a), extrapolated=0)


def point_at(window: TrajectoryWindow | PreparedWindow, s: float) -> tuple[float, float]:
    """World position of the path at window arc length s (end tangents beyond the window).

    Args:
        window: a valid trajectory window (or a PreparedWindow of it); s: arc length [m].
    """
    w = window if isinstance(window, PreparedWindow) else PreparedWindow(window)
    for end, outside in ((0, s < w.s[0]), (-1, s > w.s[-1])):
        if outside:
            along = s - w.s[end]
            return w.x[end] + along * math.cos(w.psi[end]), w.y[end] + along * math.sin(w.psi[end])
    i = min(bisect.bisect_right(w.s, s) - 1, len(w.s) - 2)
    t = (s - w.s[i]) / (w.s[i + 1] - w.s[i])
    return _hermite(w.segment(i), t, order=0)[0]
