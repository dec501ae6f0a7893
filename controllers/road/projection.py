"""Projection of a point on a trajectory window (controllers.trajectory format).

Between two window points the path is a cubic Hermite curve through both
positions with the tangents given by the headings (scaled by the arc-length
step), which matches circles and clothoids to fourth order in the point
spacing; the foot point is found on the nearest chord, then refined by Newton
iterations on that curve. The nearest chord is the global minimum over the
window (first index on ties), found from a hint chord by a descent and a scan
that skips runs of chords too far away to matter (see PreparedWindow).
Heading, curvature, speed and acceleration are interpolated linearly in arc
length; dkappa/ds is the segment's slope.

A point before the first window point or after the last one is projected on
the straight extension of the end tangent: arc length and offset follow that
line, heading, curvature, speed and acceleration hold their end values and
dkappa/ds is 0, and `extrapolated` says which end was used.
"""

from __future__ import annotations

import bisect
import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from controllers import jit
from controllers.road import hermite
from controllers.trajectory import FIELDS, TrajectoryWindow



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


# a compiled step's buffer of the two feet (projection_jit.cg_and_preview_into): the CG foot's 12
# fields (hermite's foot fields: finish's 10 with the tangent dx, dy after), the preview foot's 12,
# then the preview point's x, y
FEET_SIZE = 26
_FIELD_NAMES = frozenset(name for name, _, _ in FIELDS)   # x, y, psi, kappa, s, v, a
_all = np.logical_and.reduce      # ndarray.all without its Python wrapper (once per window)


class PreparedWindow:
    """A window with its chords precomputed and its fields as Python lists (fast scalar access).

    Besides the fields it keeps, per chord i (from point i to i + 1), the start,
    the direction and the squared length, and `reach`, the polyline length
    from point 0 to point k (the chords' cumulative length; its rounding is
    far inside the search's `slack`): the exact nearest-chord search uses it to
    skip chords that cannot be nearer than the best one found so far. Four tracking
    slots (see tracked_chord) serve points that move little between calls,
    such as a controller's CG and preview point while the window is the same.

    `compiled` is foot()'s compiled path for this window (compiled_kernel()
    bound to the window's arrays), `compiled_pair` cg_and_preview()'s and
    `compiled_feet` the kernel's cg_and_preview_into (for a compiled step that
    finishes the feet itself, see FEET_SIZE), or None for the interpreted one; the
    search state above (chords, reach, tracking slots) exists only on the
    interpreted path.

    Args:
        window: a valid trajectory window, or its fields as rows of a float64 matrix.
        compiled: True: the compiled path when it exists (loading it at the first such call);
            False: the interpreted one; None: the compiled one only if this process has
            loaded it already (never numba's load in the middle of a run).
        packed: on the compiled path, the window as the kernel's pack made it already
            (`checked`); None: packed here.
    """

    def __init__(self, window: TrajectoryWindow | np.ndarray, compiled: bool | None = None,
                 packed: np.ndarray | None = None) -> None:
        # one (field, point) matrix in controllers.trajectory.FIELDS order
        matrix = window if isinstance(window, np.ndarray) else np.array(
            [getattr(window, name) for name, _, _ in FIELDS], dtype=np.float64)
        if compiled is None:
            compiled = jit.is_loaded(compiled_kernel)
        kernel = compiled_kernel() if compiled else None
        self.compiled = self.compiled_pair = self.compiled_feet = None
        self.chords = matrix.shape[1] - 1
        self._segments: list[tuple | None] = [None] * self.chords
        if kernel is not None:      # the field lists only when asked for (__getattr__): not per tick
            if packed is None:      # pack takes a writable C-ordered array: its one compiled signature
                packed = kernel.pack(np.array(matrix, dtype=np.float64, order="C"))
            self.compiled, self.compiled_pair, self.compiled_feet = _bind(kernel, packed)
            self._matrix = matrix
            return
        self.x, self.y, self.psi, self.kappa, self.s, self.v, self.a = matrix.tolist()
        self._prepare_search(matrix)

    @classmethod
    def checked(cls, matrix: np.ndarray, compiled: bool) -> PreparedWindow | None:
        """The window of `matrix` (a fresh C-ordered float64 (fields, points) array this object
        may keep) if it passes a controller's quick test: the 7 fields, every value finite, s
        strictly increasing; else None (the caller validates it the long way, for a message).

        Args:
            matrix: the window's fields as rows, in controllers.trajectory.FIELDS order.
            compiled: the compiled path, tested and packed in one compiled call (when the
                compiled projection does not load, the interpreted path).
        """
        kernel = compiled_kernel() if compiled else None
        if kernel is not None:
            packed = kernel.checked_pack(matrix)
            return cls(matrix, True, packed) if packed.shape[1] else None
        if (matrix.shape[0] == len(FIELDS) and _all(np.isfinite(matrix), axis=None)
                and _all(matrix[4, 1:] > matrix[4, :-1])):     # row 4: s (controllers.trajectory.FIELDS)
            return cls(matrix, False)
        return None

    def __getattr__(self, name: str):
        """A field list on the compiled path, made on first use (point_at, segment read them)."""
        if name in _FIELD_NAMES and "_matrix" in self.__dict__:
            self.x, self.y, self.psi, self.kappa, self.s, self.v, self.a = self._matrix.tolist()
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _prepare_search(self, matrix: np.ndarray) -> None:
        """The interpreted path's chords, reach and tracking state (the compiled path scans every chord)."""
        delta = matrix[:2, 1:] - matrix[:2, :-1]            # chord dx, dy (as np.diff)
        square = delta * delta
        length2 = square[0] + square[1]
        self.reach = list(itertools.accumulate(np.sqrt(length2).tolist(), initial=0.0))
        # slack of the skip test: covers rounding in reach, distances and squared distances
        self.slack = 1e-9 * (1.0 + self.reach[-1] + 2.0 * float(np.maximum.reduce(abs(matrix[:2]), axis=None)))
        self.dx, self.dy = delta.tolist()
        self.length2 = np.maximum(length2, 1e-300).tolist()
        self.chord_data = list(zip(self.x, self.y, self.dx, self.dy, self.length2))   # per chord, one look-up
        # tracked_chord's state per slot: certificate (x0, y0, R, lo, hi, floor), last answer (-1: none)
        self.certs: list[tuple | None] = [None, None, None, None]
        self.best = [-1, -1, -1, -1]
        # extra radius of a certificate: four mean chords (wider: more chords measured per call,
        # narrower: more full searches; the answer does not depend on it, only the time: 2 was 5 %
        # slower in the closed loop)
        self.mean_chord = self.reach[-1] / self.chords
        self.margin = 4.0 * self.mean_chord

    def chord_distance2(self, i: int, px: float, py: float) -> tuple[float, float]:
        """Squared distance from (px, py) to chord i and the clamped chord parameter of the foot."""
        x0, y0, dx, dy, l2 = self.chord_data[i]
        t = ((px - x0) * dx + (py - y0) * dy) / l2
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        ex, ey = x0 + t * dx - px, y0 + t * dy - py
        return ex * ex + ey * ey, t

    def nearest_chord(self, px: float, py: float, hint: int = 0) -> tuple[int, float]:
        """Index of the nearest chord (the first one on ties) and the clamped chord parameter of the foot.

        The answer is the global minimum over all chords, as a full scan would
        give; `hint` (e.g. the previous answer) only makes it faster.

        Args:
            px, py: the point; hint: chord index to start from.
        """
        i, t, _ = self._search(px, py, hint, 0.0)
        return i, t

    def tracked_chord(self, px: float, py: float, slot: int) -> tuple[int, float]:
        """nearest_chord for a point that moves little between calls (same answer, usually faster).

        Each slot (one per tracked point, e.g. 0 the CG, 1 the preview point)
        keeps a certificate from its last full search at p0: every chord
        outside the index range [lo, hi] is farther than R from p0, and chord
        k inside it at least floor[k] away (kept as (floor[k], k) pairs, floor
        ascending). For a point p within d of p0, only the chords of lo..hi
        whose floor[k] - d does not exceed the best distance are measured; if
        the best is nearer than R - d, no other chord can be nearer. Otherwise
        a full search renews the certificate.

        Args:
            px, py: the point; slot: 0 to 3.
        """
        cert = self.certs[slot]
        if cert is not None:
            x0, y0, radius, lo, hi, floor = cert
            moved = math.hypot(px - x0, py - y0)
            if moved < radius:
                i = self.best[slot]
                chords = self.chord_data
                x0, y0, dx, dy, l2 = chords[i]        # chord_distance2, inlined
                t = ((px - x0) * dx + (py - y0) * dy) / l2
                best_t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
                ex, ey = x0 + best_t * dx - px, y0 + best_t * dy - py
                best_d = ex * ex + ey * ey
                # chord k can only beat the best if floor[k] - moved (its least distance now) does
                bound = math.sqrt(best_d) + self.slack + moved
                # floor ascending: once a floor exceeds the bound (which only shrinks), so do the rest;
                # the skipped chords are farther than the best, so the order does not change the answer
                for least, k in floor:
                    if least > bound:
                        break
                    if k == i:
                        continue
                    x0, y0, dx, dy, l2 = chords[k]        # chord_distance2, inlined
                    t = ((px - x0) * dx + (py - y0) * dy) / l2
                    t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
                    ex, ey = x0 + t * dx - px, y0 + t * dy - py
                    d = ex * ex + ey * ey
                    if d < best_d or (d == best_d and k < i):
                        i, best_d, best_t = k, d, t
                        bound = math.sqrt(d) + self.slack + moved
                if math.sqrt(best_d) + self.slack < radius - moved:
                    self.best[slot] = i
                    return i, best_t
        hint = self.best[slot]
        i, t, cert = self._search(px, py, hint if hint >= 0 else max(self.best), self.margin)
        self.certs[slot], self.best[slot] = (px, py, *cert), i
        return i, t

    def _descend(self, px: float, py: float, hint: int, seen: list) -> tuple:
        """From chord `hint`, step to the nearer neighbour while distances fall (ties to the left).

        Returns (chord, squared distance, chord parameter, lo, hi), lo..hi the chords
        measured; each measured (chord, squared distance) is appended to `seen`.
        """
        distance2, last = self.chord_distance2, self.chords - 1
        i = min(max(hint, 0), last)
        best_d, best_t = distance2(i, px, py)
        seen.append((i, best_d))
        lo = hi = i
        while lo > 0:
            d, t = distance2(lo - 1, px, py)
            lo -= 1
            seen.append((lo, d))
            if d > best_d:
                break
            i, best_d, best_t = lo, d, t
        while hi < last and hi == i:
            d, t = distance2(hi + 1, px, py)
            hi += 1
            seen.append((hi, d))
            if d < best_d:
                i, best_d, best_t = hi, d, t
        return i, best_d, best_t, lo, hi

    def _search(self, px: float, py: float, hint: int, margin: float) -> tuple[int, float, tuple]:
        """Full exact search: (chord, chord parameter, (R, lo, hi, floor)) with R = best distance + margin,
        every chord outside lo..hi farther than R and chord k of lo..hi at least floor[k - lo] away
        (floor as the (floor[k - lo], k) pairs of lo..hi, sorted).

        A descent from `hint` finds a near chord, then the chords on each side
        are scanned, skipping runs whose polyline reach from an anchor point
        proves them farther than the best distance so far plus `margin`.
        """
        distance2, last, seen = self.chord_distance2, self.chords - 1, []
        i, best_d, best_t, lo, hi = self._descend(px, py, hint, seen)
        xs, ys, reach, slack = self.x, self.y, self.reach, self.slack
        hypot, sqrt = math.hypot, math.sqrt
        limit = sqrt(best_d) + margin + slack
        j = hi + 1
        while j <= last:           # chords j..m lie within reach[m + 1] - reach[j] of point j
            m = bisect.bisect_left(reach, reach[j] + hypot(px - xs[j], py - ys[j]) - limit) - 2
            if m >= j:
                j = m + 1
                continue
            d, t = distance2(j, px, py)
            seen.append((j, d))
            if d < best_d:
                i, best_d, best_t, limit = j, d, t, sqrt(d) + margin + slack
            j += 1
        j = lo - 1
        while j >= 0:              # chords m..j lie within reach[j + 1] - reach[m] of point j + 1
            m = bisect.bisect_right(reach, reach[j + 1] - hypot(px - xs[j + 1], py - ys[j + 1]) + limit)
            if m <= j:
                j = m - 1
                continue
            d, t = distance2(j, px, py)
            seen.append((j, d))
            if d <= best_d:        # a lower index wins a tie
                i, best_d, best_t, limit = j, d, t, sqrt(d) + margin + slack
            j -= 1
        radius = sqrt(best_d) + margin
        near = [k for k, d in seen if sqrt(d) <= radius]
        lo, hi = min(near), max(near)
        floor = [radius] * (hi - lo + 1)        # chords in lo..hi not measured were proven beyond radius
        for k, d in seen:
            if lo <= k <= hi:
                floor[k - lo] = min(floor[k - lo], sqrt(d))
        return i, best_t, (radius, lo, hi, sorted(zip(floor, range(lo, hi + 1))))

    def segment(self, i: int) -> tuple[float, ...]:
        """End positions and end tangents (scaled by the arc-length step) of segment i (kept once made)."""
        seg = self._segments[i]
        if seg is None:
            seg = self._segments[i] = hermite.segment(self.x, self.y, self.s, self.psi, i)
        return seg


def _bind(kernel, packed: np.ndarray) -> tuple[functools.partial, functools.partial, functools.partial]:
    """kernel's foot_fields, cg_and_preview_fields and cg_and_preview_into on a packed window
    (kernel.pack's, once for all three)."""
    return (functools.partial(kernel.foot_fields, packed), functools.partial(kernel.cg_and_preview_fields, packed),
            functools.partial(kernel.cg_and_preview_into, packed))


@functools.cache
def compiled_kernel():
    """The controllers.road.projection_jit module (foot_fields, pack, checked_pack), or None for the interpreted path.

    controllers.jit.load_compiled decides (COSIM_JIT; numba missing or broken;
    the compiled code checked bit for bit against the interpreted path on a
    built-in set of points). The first call imports numba and loads (or
    compiles) the code.
    """
    return jit.load_compiled("the compiled projection", _import_kernel, _disagreement)


def _import_kernel():
    from controllers.road import projection_jit
    return projection_jit


def _disagreement(kernel) -> str:
    """'' if kernel gives foot()'s tuples bit for bit on a test window, else the first point where it does not.

    Compared by repr, which tells -0.0 from 0.0, 0 from 0.0 and a numpy scalar from a float.
    The window is packed by checked_pack, a controller's path, which must also agree with
    pack and refuse what InputReader's quick test refuses.
    """
    s = np.linspace(0.0, 62.0, 32)
    psi = 0.3 + 0.012 * s + 0.0004 * s * s
    matrix = np.array([40.0 + 30.0 * np.sin(psi) + 0.9 * s, -5.0 - 30.0 * np.cos(psi), psi,
                       0.012 + 0.0008 * s, s, 8.0 + 0.05 * s, 0.05 + 0.0 * s])
    packed = kernel.checked_pack(matrix)
    if packed.tobytes() != kernel.pack(matrix).tobytes():
        return "checked_pack packs the test window unlike pack"
    for row, column, value in ((2, 5, math.nan), (6, 0, -math.inf), (4, 9, s[8])):
        bad = matrix.copy()
        bad[row, column] = value
        if kernel.checked_pack(bad).shape[1]:
            return f"checked_pack accepts a window with {value} at row {row}, point {column}"
    if kernel.checked_pack(np.array(matrix[:6])).shape[1]:
        return "checked_pack accepts a window of 6 fields"
    interpreted, (bound, pair, into) = PreparedWindow(matrix, compiled=False), _bind(kernel, packed)
    feet = np.zeros(FEET_SIZE)
    for px in np.linspace(-20.0, 130.0, 31).tolist():
        for py in np.linspace(-60.0, 40.0, 21).tolist():
            expected, got = foot(interpreted, px, py), finish(bound(px, py), px, py)
            if repr(got) != repr(expected):
                return f"at ({px}, {py}) it gives {got}, the interpreted path {expected}"
            cg, preview, ax, ay = pair(px, py, 0.7, 6.0)
            expected = (foot(interpreted, px, py), foot(interpreted, px + 6.0 * math.cos(0.7),
                                                        py + 6.0 * math.sin(0.7)))
            if repr((finish(cg, px, py), finish(preview, ax, ay))) != repr(expected):
                return f"at ({px}, {py}) cg_and_preview disagrees with two foot() calls"
            dx_cg, dy_cg, dx_preview, dy_preview = into(px, py, 0.7, 6.0, feet)
            got = (kernel.finished(feet, 0, px, py, math.hypot(dx_cg, dy_cg)),
                   kernel.finished(feet, 12, feet[24], feet[25], math.hypot(dx_preview, dy_preview)))
            if repr(got) != repr(expected):
                return f"at ({px}, {py}) cg_and_preview_into and finished disagree with two foot() calls"
    return ""


def _hermite(seg: tuple[float, ...], t: float, order: int = 2) -> list[tuple[float, float]]:
    """Position and t-derivatives up to `order` of the Hermite curve of a segment (scalar math)."""
    x0, y0, mx0, my0, x1, y1, mx1, my1 = seg
    t2, t3 = t * t, t * t * t
    weights = ((2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2),
               (6.0 * t2 - 6.0 * t, 3.0 * t2 - 4.0 * t + 1.0, -6.0 * t2 + 6.0 * t, 3.0 * t2 - 2.0 * t),
               (12.0 * t - 6.0, 6.0 * t - 4.0, -12.0 * t + 6.0, 6.0 * t - 2.0))
    return [(w[0] * x0 + w[1] * mx0 + w[2] * x1 + w[3] * mx1,
             w[0] * y0 + w[1] * my0 + w[2] * y1 + w[3] * my1) for w in weights[:order + 1]]


def foot(w: PreparedWindow, px: float, py: float, slot: int = -1) -> tuple:
    """project() as a plain tuple, for the controllers' per-tick path.

    Args:
        w: a PreparedWindow of a valid window; px, py: the point [m];
        slot: PreparedWindow.tracked_chord's slot for a point tracked from call
            to call (same answer, faster), or -1 for a one-off point.
    Returns:
        (s, x, y, offset, psi_path, kappa, dkappa_ds, v, a, extrapolated): the Projection's fields.
    """
    if w.compiled is not None:       # float(): the one compiled signature, and floats out as inside
        px, py = float(px), float(py)
        return finish(w.compiled(px, py), px, py)
    i, t = w.tracked_chord(px, py, slot) if slot >= 0 else w.nearest_chord(px, py)
    if i == 0 and t == 0.0:
        fields = hermite.beyond(0, px, py, w.x, w.y, w.s, w.psi, w.kappa, w.v, w.a)
        if fields[9]:
            return fields[:10]
    if i == w.chords - 1 and t == 1.0:
        fields = hermite.beyond(-1, px, py, w.x, w.y, w.s, w.psi, w.kappa, w.v, w.a)
        if fields[9]:
            return fields[:10]
    seg = w._segments[i] or w.segment(i)
    return finish(hermite.evaluate(seg, hermite.refine(seg, t, px, py), i, w.s, w.psi, w.kappa, w.v, w.a), px, py)


def cg_and_preview(w: PreparedWindow, x: float, y: float, psi: float, ls: float) -> tuple[tuple, tuple]:
    """foot() of the CG (tracking slot 0) and of the preview point ls ahead along psi (slot 1).

    Args:
        w: a PreparedWindow of a valid, non-empty window; x, y, psi: the CG and the heading;
        ls: preview distance [m].
    """
    if w.compiled_pair is not None:
        x, y = float(x), float(y)
        at_cg, preview, px, py = w.compiled_pair(x, y, float(psi), float(ls))
        return finish(at_cg, x, y), finish(preview, px, py)
    at_cg = foot(w, x, y, 0)
    if w.best[1] < 0 and w.mean_chord > 0.0:   # a new window: start the preview's search ls ahead of the CG's
        w.best[1] = w.best[0] + round(ls / w.mean_chord)
    return at_cg, foot(w, x + ls * math.cos(psi), y + ls * math.sin(psi), 1)


def finish(fields: tuple, px: float, py: float) -> tuple:
    """foot()'s tuple from controllers.road.hermite's foot fields: the offset from the tangent inside the window.

    math.hypot stays here, in the interpreter, for both paths: CPython's
    algorithm is not libm's, and a compiled copy would differ in the last bit.
    """
    if fields[9]:
        return fields[:10]
    s, x, y, _, psi, kappa, dkappa, v, a, _, dx, dy = fields
    return (s, x, y, (dx * (py - y) - dy * (px - x)) / max(math.hypot(dx, dy), 1e-300), psi, kappa, dkappa,
            v, a, 0)


def project(window: TrajectoryWindow | PreparedWindow, px: float, py: float) -> Projection:
    """Project the point (px, py) on the window (assumed valid: see validate_window).

    Args:
        window: the trajectory window, or a PreparedWindow of it (faster for several points).
        px, py: world coordinates of the point [m].
    Returns:
        The Projection of the point (see its attributes).
    """
    w = window if isinstance(window, PreparedWindow) else PreparedWindow(window)
    return Projection(*foot(w, px, py))


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
