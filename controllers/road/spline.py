"""C2 cubic splines through waypoints, sampled as path knots (for controllers.road.geometry).

`spline_knots` fits a natural (open) or periodic (closed) cubic spline through
the points, parameterised by chord length, and samples it: arc length (by
10-point Gauss-Legendre quadrature of the speed over each sample interval),
position, heading and curvature at each sample. `Path.from_waypoints` builds a
path from these knots.
"""

from __future__ import annotations

import numpy as np

from controllers.spec import SpecError

_GL_T, _GL_W = np.polynomial.legendre.leggauss(10)


def _spline_second_derivatives(t: np.ndarray, v: np.ndarray, closed: bool) -> np.ndarray:
    """Knot second derivatives M of the natural / periodic cubic spline v(t)."""
    h = np.diff(t)
    n = v.size
    a = np.zeros((n, n))
    rhs = np.zeros(n)
    rows = range(n - 1) if closed else range(1, n - 1)
    for i in rows:
        hp, hn = h[i - 1], h[i]
        im = (i - 1) % (n - 1)                    # periodic: point n-1 is point 0
        ip = (i + 1) % (n - 1) if closed else i + 1
        a[i, im] += hp
        a[i, i] += 2 * (hp + hn)
        a[i, ip] += hn
        rhs[i] = 6 * ((v[i + 1] - v[i]) / hn - (v[i] - v[im]) / hp)
    if closed:
        a[n - 1, n - 1], a[n - 1, 0] = 1.0, -1.0     # M_last = M_0
    else:
        a[0, 0] = a[n - 1, n - 1] = 1.0
    return np.linalg.solve(a, rhs)


def _spline_eval(t, v, m, j, u):
    """Value, first and second derivative of span j of the spline at local u."""
    h = t[j + 1] - t[j]
    b = h - u
    val = m[j] * b ** 3 / (6 * h) + m[j + 1] * u ** 3 / (6 * h) \
        + (v[j] / h - m[j] * h / 6) * b + (v[j + 1] / h - m[j + 1] * h / 6) * u
    d1 = -m[j] * b ** 2 / (2 * h) + m[j + 1] * u ** 2 / (2 * h) \
        - (v[j] / h - m[j] * h / 6) + (v[j + 1] / h - m[j + 1] * h / 6)
    d2 = (m[j] * b + m[j + 1] * u) / h
    return val, d1, d2


def spline_knots(points: np.ndarray, closed: bool, per_span: int):
    """Sample a C2 spline through points: arc length, x, y, heading, curvature.

    Args:
        points: (n, 2) world positions; for a closed spline the first is not repeated.
        closed: periodic spline (the samples end back at the first point).
        per_span: samples per span between two points.

    Raises:
        SpecError: too few, non-finite or coincident points.
    """
    if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < (3 if closed else 2):
        raise SpecError(f"waypoints must be a list of at least {3 if closed else 2} [x, y] pairs")
    if not np.all(np.isfinite(points)):
        raise SpecError("waypoints contain a non-finite coordinate")
    if closed:
        points = np.vstack([points, points[:1]])
    chord = np.hypot(*np.diff(points, axis=0).T)
    if np.any(chord <= 0):
        raise SpecError(f"waypoints {int(np.argmin(chord))} and {int(np.argmin(chord)) + 1} coincide")
    t = np.concatenate([[0.0], np.cumsum(chord)])
    mx = _spline_second_derivatives(t, points[:, 0], closed)
    my = _spline_second_derivatives(t, points[:, 1], closed)
    span = np.repeat(np.arange(chord.size), per_span)
    frac = np.tile(np.arange(per_span) / per_span, chord.size)
    span = np.append(span, chord.size - 1)
    u = np.append(frac * chord[span[:-1]], chord[-1])
    x, dx, ddx = _spline_eval(t, points[:, 0], mx, span, u)
    y, dy, ddy = _spline_eval(t, points[:, 1], my, span, u)
    speed = np.hypot(dx, dy)
    ua, ub = u[:-1], np.where(span[1:] == span[:-1], u[1:], chord[span[:-1]])
    q = ua[:, None] + 0.5 * (_GL_T[None, :] + 1) * (ub - ua)[:, None]
    _, qx, _ = _spline_eval(t, points[:, 0], mx, span[:-1, None], q)
    _, qy, _ = _spline_eval(t, points[:, 1], my, span[:-1, None], q)
    seg = 0.5 * (ub - ua) * (np.hypot(qx, qy) @ _GL_W)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    psi = np.unwrap(np.arctan2(dy, dx))
    kappa = (dx * ddy - dy * ddx) / speed ** 3
    return s, x, y, psi, kappa
