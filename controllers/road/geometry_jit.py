"""A Path's foot-point Newton iteration compiled by numba (the `jit` extra): the same bits as interpreted.

Imported only through controllers.road.compiled_path's gate (`compiled_geometry`:
COSIM_JIT, a bit-for-bit check at first use). `newton` and `point` are
Path._newton and Path._point written on one (10, knots) float64 array of the
path's knot lists (Path._lists) and the quadrature's fractions and weights, with
Python's min and max spelled out (`b if b > a else a`: the first argument on ties
and signed zeros, as the builtins give). A twin written by hand, not compiled from
geometry.py's source: an edit of Path._point or Path._newton that changes their
bits must be made here too, else the gate's check finds the difference and the
interpreted search is used (a warning; an error with COSIM_JIT=on). Cached on
disk by numba beside this file, which numba's cache sees edited.
"""

from __future__ import annotations

import math

import numba  # noqa: F401  (ImportError without numba: the interpreted projection)
import numpy as np

from controllers import jit

_compile = jit.njit_cached


@_compile
def point(knots, closed, length, fractions, weights, s):
    """Path._point: world (x, y, psi, kappa) at arc length s.

    Args:
        knots: rows s, interval length, psi, kappa0, dkappa, x, x error, y, y error, psi error
            (Path._lists; the interval rows one shorter, padded);
        closed, length: the path's; fractions, weights: geometry._GL_FRACTIONS as two arrays.
    """
    if closed:
        s = s % length
    beyond = 0.0
    if not closed and not 0.0 <= s <= length:
        if s < 0.0:
            beyond, s = s, 0.0
        else:
            beyond, s = s - length, length
    intervals = knots.shape[1] - 1
    i = np.searchsorted(knots[0], s, side="right") - 1      # bisect.bisect_right(s list, s) - 1
    i = 0 if not i > 0 else i
    i = intervals - 1 if intervals - 1 < i else i
    u = s - knots[0, i]
    psi_i, k0, dk = knots[2, i], knots[3, i], knots[4, i]
    cx = sy = 0.0
    half_dk = 0.5 * dk
    for n in range(fractions.size):
        v = fractions[n] * u
        ph = psi_i + k0 * v + half_dk * v * v
        cx += weights[n] * math.cos(ph)
        sy += weights[n] * math.sin(ph)
    frac = u / knots[1, i]
    x = knots[5, i] + 0.5 * u * cx + frac * knots[6, i]
    y = knots[7, i] + 0.5 * u * sy + frac * knots[8, i]
    psi = psi_i + k0 * u + 0.5 * dk * u * u + frac * knots[9, i]
    if beyond:
        return x + beyond * math.cos(psi), y + beyond * math.sin(psi), psi, 0.0
    return x, y, psi, k0 + dk * u


@_compile
def newton(knots, closed, length, fractions, weights, max_interval, px, py, s):
    """Path._newton: the foot point's arc length from s, or NaN where it gives None (no convergence)."""
    for _ in range(30):
        x, y, psi, kap = point(knots, closed, length, fractions, weights, s)
        dx, dy = px - x, py - y
        f = dx * math.cos(psi) + dy * math.sin(psi)
        slope = 1.0 - kap * (-dx * math.sin(psi) + dy * math.cos(psi))
        step = f / slope if slope > 0.1 else f
        step = -max_interval if -max_interval > step else step          # max(step, -max_interval)
        step = max_interval if max_interval < step else step            # min(step, max_interval)
        s_new = s + step
        if not closed:
            s_new = 0.0 if 0.0 > s_new else s_new                       # max(s_new, 0.0)
            s_new = length if length < s_new else s_new                 # min(s_new, length)
        if abs(s_new - s) < 1e-10:
            return s_new
        s = s_new
    return math.nan


def recompile() -> None:
    """Compile both functions afresh (and replace their cache entries), point first."""
    point.recompile()
    newton.recompile()
