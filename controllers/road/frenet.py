"""Road (Frenet) coordinates: an offset profile d(s) along a reference path, in the world.

`frenet_to_world` turns a lateral offset profile d(s) (left positive) along a
reference path into a world trajectory with exact heading, curvature and
arc-length rate; `frenet_from_base` does the same on reference samples
already evaluated. Used by the road builders, the OpenDRIVE reader and the planner.
"""

from __future__ import annotations

import numpy as np

from controllers.road.geometry import Path, SpecError

_any = np.logical_or.reduce     # ndarray.any without its Python wrapper (every planner step)


def frenet_to_world(path: Path, s, d, dd, ddd):
    """World trajectory of the offset profile d(s) along a reference path.

    Args:
        path: the reference line.
        s: reference arc lengths (array).
        d, dd, ddd: lateral offset and its first and second derivative in s.

    Returns:
        x, y, psi, kappa of the trajectory and g = d sigma / ds, the rate of
        its own arc length sigma per reference arc length.
    """
    s = np.asarray(s, dtype=float)
    x0, y0, psi0, k = path.evaluate(s)
    return frenet_from_base((x0, y0, psi0, k, path.dkappa(s)), d, dd, ddd, s)


def frenet_from_base(base, d, dd, ddd, s=None, trig=None):
    """`frenet_to_world` on reference samples already evaluated.

    Args:
        base: (x, y, psi, kappa, dkappa/ds) of the reference line at the stations.
        d, dd, ddd: lateral offset and its first two derivatives in s there.
        s: the stations (only for error messages).
        trig: (sin psi, cos psi) of the reference there if known (saves their
            evaluation at every planner step; the same values bit for bit).
    """
    x0, y0, psi0, k, dk = base
    d, dd, ddd = np.asarray(d, dtype=float), np.asarray(dd, dtype=float), np.asarray(ddd, dtype=float)
    a = 1.0 - k * d
    if _any(a <= 0.0):
        bad = int(np.argmax(a <= 0.0))
        where = f" at s = {s[bad]:.3f} m" if s is not None else ""
        raise SpecError(f"lateral offset {d[bad]:.3f} m{where} crosses the road's "
                        f"centre of curvature (radius {1.0 / k[bad]:.3f} m)")
    a1 = -(dk * d + k * dd)
    g = np.hypot(a, dd)
    sin_psi, cos_psi = (np.sin(psi0), np.cos(psi0)) if trig is None else trig
    x = x0 - d * sin_psi
    y = y0 + d * cos_psi
    psi = psi0 + np.arctan2(dd, a)
    kappa = (a * (a * k + ddd) - dd * (a1 - dd * k)) / g ** 3
    return x, y, psi, kappa, g
