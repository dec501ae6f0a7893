"""The projection's arithmetic on one window segment, in a form numba can compile unchanged.

Each function takes plain floats, tuples and indexable sequences (Python
lists in controllers.road.projection's interpreted path, numpy arrays in
controllers.road.projection_jit's compiled one) and calls nothing but `math` (numba
compiles each function on its own, so none calls another),
so the same source gives the same IEEE operations in the same order on both
paths: bit-identical results. The one operation the compiled path cannot
reproduce, `math.hypot` (CPython's own algorithm, not libm's), is left to the
caller (see `finish` in controllers.road.projection).

A segment joins window points i and i + 1 by a cubic Hermite curve:
(x0, y0, mx0, my0, x1, y1, mx1, my1), the end positions and end tangents
scaled by the arc-length step.

Foot fields, as returned here: (s, x, y, offset, psi_path, kappa, dkappa_ds,
v, a, extrapolated, tx, ty), the Projection's fields followed by the path
tangent at the foot; inside the window the offset is left at 0.0 for the
caller to compute from the tangent, beyond an end it is exact already.
"""

from __future__ import annotations

import math

NEWTON_ITERATIONS = 4


def segment(xs, ys, s, psi, i: int) -> tuple:
    """The Hermite segment from window point i to i + 1."""
    step = s[i + 1] - s[i]
    psi0, psi1 = psi[i], psi[i + 1]
    return (xs[i], ys[i], step * math.cos(psi0), step * math.sin(psi0),
            xs[i + 1], ys[i + 1], step * math.cos(psi1), step * math.sin(psi1))


def refine(seg: tuple, t: float, px: float, py: float) -> float:
    """Newton iterations for the foot parameter of (px, py) on the segment, from chord parameter t.

    The Hermite weights are written out (projection._hermite's expressions):
    this is the projection's inner loop.
    """
    x0, y0, mx0, my0, x1, y1, mx1, my1 = seg
    for _ in range(NEWTON_ITERATIONS):
        t2 = t * t
        t3 = t2 * t           # t * t * t
        w0, w1, w2, w3 = 2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2
        ex = w0 * x0 + w1 * mx0 + w2 * x1 + w3 * mx1 - px
        ey = w0 * y0 + w1 * my0 + w2 * y1 + w3 * my1 - py
        w0, w1, w2, w3 = 6.0 * t2 - 6.0 * t, 3.0 * t2 - 4.0 * t + 1.0, -6.0 * t2 + 6.0 * t, 3.0 * t2 - 2.0 * t
        dx = w0 * x0 + w1 * mx0 + w2 * x1 + w3 * mx1
        dy = w0 * y0 + w1 * my0 + w2 * y1 + w3 * my1
        w0, w1, w2, w3 = 12.0 * t - 6.0, 6.0 * t - 4.0, -12.0 * t + 6.0, 6.0 * t - 2.0
        ddx = w0 * x0 + w1 * mx0 + w2 * x1 + w3 * mx1
        ddy = w0 * y0 + w1 * my0 + w2 * y1 + w3 * my1
        slope = dx * dx + dy * dy + ex * ddx + ey * ddy
        if slope <= 0.0:
            break
        new_t = t - (ex * dx + ey * dy) / slope
        # min(1.0, max(0.0, new_t)) without the two calls (same result, NaN and -0.0 included)
        new_t = (new_t if new_t < 1.0 else 1.0) if new_t > 0.0 else 0.0
        if abs(new_t - t) < 1e-13:
            return new_t
        t = new_t
    return t


def evaluate(seg: tuple, t: float, i: int, s, psi, kappa, v, a) -> tuple:
    """Foot fields at parameter t of segment i (refine's answer; offset left at 0.0)."""
    x0, y0, mx0, my0, x1, y1, mx1, my1 = seg
    t2 = t * t
    t3 = t2 * t               # t * t * t
    w0, w1, w2, w3 = 2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2
    x = w0 * x0 + w1 * mx0 + w2 * x1 + w3 * mx1
    y = w0 * y0 + w1 * my0 + w2 * y1 + w3 * my1
    w0, w1, w2, w3 = 6.0 * t2 - 6.0 * t, 3.0 * t2 - 4.0 * t + 1.0, -6.0 * t2 + 6.0 * t, 3.0 * t2 - 2.0 * t
    dx = w0 * x0 + w1 * mx0 + w2 * x1 + w3 * mx1
    dy = w0 * y0 + w1 * my0 + w2 * y1 + w3 * my1
    j = i + 1
    step, rise = s[j] - s[i], kappa[j] - kappa[i]
    return (s[i] + t * step, x, y, 0.0, psi[i] + t * (psi[j] - psi[i]), kappa[i] + t * rise, rise / step,
            v[i] + t * (v[j] - v[i]), a[i] + t * (a[j] - a[i]), 0, dx, dy)


def beyond(end: int, px: float, py: float, xs, ys, s, psi, kappa, v, a) -> tuple:
    """Foot fields on the tangent line at window point `end` (0 or -1).

    extrapolated (field 9) is -1 or +1 when the point lies beyond that end,
    0 when it does not (the other fields are then meaningless).
    """
    heading = psi[end]
    tx, ty = math.cos(heading), math.sin(heading)
    along = (px - xs[end]) * tx + (py - ys[end]) * ty
    side = -1 if end == 0 else 1
    if (side < 0 and along >= 0.0) or (side > 0 and along <= 0.0):
        side = 0
    offset = -(px - xs[end]) * ty + (py - ys[end]) * tx
    return (s[end] + along, xs[end] + along * tx, ys[end] + along * ty, offset, heading,
            kappa[end], 0.0, v[end], a[end], side, tx, ty)
