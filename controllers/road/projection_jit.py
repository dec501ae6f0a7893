"""The window projection compiled by numba (the `jit` extra): the same bits as the interpreted path.

Imported only by controllers.road.projection, and only when numba is
installed and COSIM_JIT does not turn it off. controllers.road.hermite's
functions are compiled from their own source; the nearest chord is a plain
scan of every chord (first index on ties), which is the answer the
interpreted path's certified search proves without measuring them all, and
in compiled code the scan of a 63-chord window is cheaper than the proof.
Compiled functions are cached on disk by numba (`cache=True`, in
`__pycache__` beside the sources, else numba's user cache or NUMBA_CACHE_DIR):
the first run on a machine compiles them, later runs load them. With no
writable cache folder each process compiles them (a warning says so). numba
notices an edit of this file but not of hermite.py, whose functions the ones
here inline: `recompile()` rebuilds them (controllers.road.projection calls it
when its start-up check finds a stale cache).
"""

from __future__ import annotations

import math

import numba  # noqa: F401  (ImportError without numba: the interpreted projection)
import numpy as np

from controllers import jit
from controllers.road import hermite


_compile = jit.njit_cached
_segment = _compile(hermite.segment)
_refine = _compile(hermite.refine)
_evaluate = _compile(hermite.evaluate)
_beyond = _compile(hermite.beyond)


@_compile
def pack(matrix):
    """foot_fields' window from a (7, points) matrix in controllers.trajectory.FIELDS order.

    Rows x, y, s, psi, kappa, v, a, then dx, dy and max(dx * dx + dy * dy, 1e-300)
    per chord (as PreparedWindow computes them), the last column of those three 0.
    """
    points = matrix.shape[1]
    window = np.zeros((10, points))
    for row, field in enumerate((0, 1, 4, 2, 3, 5, 6)):     # FIELDS: x, y, psi, kappa, s, v, a
        window[row] = matrix[field]
    for k in range(points - 1):
        dx = matrix[0, k + 1] - matrix[0, k]
        dy = matrix[1, k + 1] - matrix[1, k]
        window[7, k] = dx
        window[8, k] = dy
        window[9, k] = max(dx * dx + dy * dy, 1e-300)
    return window


@_compile
def checked_pack(matrix):
    """pack(matrix) when the matrix passes InputReader's quick test of a window (every value
    finite, row 4, s, strictly increasing), else an empty (10, 0) array: the test and the
    packing in one call, for a controller's new window. A matrix of other than the 7 rows of
    the fields is refused too (numba does not check bounds)."""
    rows, points = matrix.shape
    if rows != 7:
        return np.zeros((10, 0))
    for row in range(rows):
        for k in range(points):
            if not math.isfinite(matrix[row, k]):
                return np.zeros((10, 0))
    for k in range(points - 1):
        if not matrix[4, k + 1] > matrix[4, k]:
            return np.zeros((10, 0))
    return pack(matrix)


@_compile
def foot_fields(window, px, py):
    """controllers.road.hermite's foot fields of (px, py) on a window.

    Args:
        window: a (10, points) float64 array, rows x, y, s, psi, kappa, v, a, then per chord
            (first points - 1 columns) dx, dy and max(squared length, 1e-300);
        px, py: the point.
    """
    xs, ys, s, psi, kappa, v, a = window[0], window[1], window[2], window[3], window[4], window[5], window[6]
    chords = window.shape[1] - 1
    dx, dy, length2 = window[7], window[8], window[9]
    best_d = math.inf
    i = 0
    t = 0.0
    for k in range(chords):      # PreparedWindow.chord_distance2 for every chord
        x0 = xs[k]
        y0 = ys[k]
        tk = ((px - x0) * dx[k] + (py - y0) * dy[k]) / length2[k]
        tk = 0.0 if tk < 0.0 else (1.0 if tk > 1.0 else tk)
        ex = x0 + tk * dx[k] - px
        ey = y0 + tk * dy[k] - py
        d = ex * ex + ey * ey
        if d < best_d:
            best_d, i, t = d, k, tk
    if i == 0 and t == 0.0:
        fields = _beyond(0, px, py, xs, ys, s, psi, kappa, v, a)
        if fields[9] != 0:
            return fields
    if i == chords - 1 and t == 1.0:
        fields = _beyond(-1, px, py, xs, ys, s, psi, kappa, v, a)
        if fields[9] != 0:
            return fields
    seg = _segment(xs, ys, s, psi, i)
    return _evaluate(seg, _refine(seg, t, px, py), i, s, psi, kappa, v, a)


@_compile
def cg_and_preview_fields(window, x, y, psi, ls):
    """foot_fields of (x, y) and of the point ls ahead along psi, and that point's coordinates."""
    px = x + ls * math.cos(psi)
    py = y + ls * math.sin(psi)
    return foot_fields(window, x, y), foot_fields(window, px, py), px, py


@_compile
def cg_and_preview_into(window, x, y, psi, ls, feet):
    """cg_and_preview_fields written into `feet` (FEET_SIZE float64s, the layout of
    controllers.road.projection.FEET_SIZE); returns the two feet's tangents (dx, dy of the CG's,
    then of the preview point's), whose math.hypot the caller takes in the interpreter for
    `finished`. A float crosses back per tangent instead of two tuples of foot fields."""
    px = x + ls * math.cos(psi)
    py = y + ls * math.sin(psi)
    at_cg = foot_fields(window, x, y)
    preview = foot_fields(window, px, py)
    feet[0], feet[1], feet[2], feet[3], feet[4], feet[5] = at_cg[0], at_cg[1], at_cg[2], at_cg[3], at_cg[4], at_cg[5]
    feet[6], feet[7], feet[8], feet[9], feet[10], feet[11] = at_cg[6], at_cg[7], at_cg[8], at_cg[9], at_cg[10], at_cg[11]
    feet[12], feet[13], feet[14], feet[15], feet[16], feet[17] = (preview[0], preview[1], preview[2], preview[3],
                                                                   preview[4], preview[5])
    feet[18], feet[19], feet[20], feet[21], feet[22], feet[23] = (preview[6], preview[7], preview[8], preview[9],
                                                                   preview[10], preview[11])
    feet[24], feet[25] = px, py
    return at_cg[10], at_cg[11], preview[10], preview[11]


@_compile
def finished(feet, start, px, py, norm):
    """controllers.road.projection.finish of the foot fields at feet[start:start + 12] for the point
    (px, py), given norm = math.hypot(dx, dy) of their tangent (taken in the interpreter: CPython's
    hypot is not libm's). The same operations in the same order as finish: the same bits; a
    twin by hand, so an edit of finish must be made here too (the gate's check finds it)."""
    side = int(feet[start + 9])
    offset = feet[start + 3]
    if side == 0:
        dx, dy = feet[start + 10], feet[start + 11]
        offset = (dx * (py - feet[start + 2]) - dy * (px - feet[start + 1])) / max(norm, 1e-300)
    return (feet[start], feet[start + 1], feet[start + 2], offset, feet[start + 4], feet[start + 5],
            feet[start + 6], feet[start + 7], feet[start + 8], side)


def recompile() -> None:
    """Compile every function here afresh (and replace their cache entries), hermite's first."""
    for function in (_segment, _refine, _evaluate, _beyond, pack, checked_pack, foot_fields,
                     cg_and_preview_fields, cg_and_preview_into, finished):
        function.recompile()
