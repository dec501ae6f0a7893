"""Planar paths parameterised by arc length: evaluation, projection, offsets.

A `Path` is a chain of knots at arc lengths s_0 = 0 < s_1 < ... < s_n = L, each
with a world position and heading, and between two knots a curvature that is
linear in s (lines, arcs and clothoids are exact). Inside an interval the
heading is the exact integral of that curvature and the position is the
integral of (cos psi, sin psi) by 10-point Gauss-Legendre quadrature; intervals
are short enough (heading change <= 0.2 rad) for the quadrature to be exact to
rounding. Paths built from other data (spline waypoints, offsets) store their
knots from that data and blend the tiny mismatch of the integral linearly over
the interval, so the path is continuous in any case.

Paths come from line/arc/clothoid segments, from a curvature profile kappa(s),
or from waypoints (C2 cubic spline through them, see `controllers.road.spline`);
`Path.from_spec` reads the YAML form. A closed path wraps s modulo its length;
an open path extends along its end tangents beyond [0, L]. Angles in specs are
degrees; everything else SI. `SpecError` and `spec_number` live in
`controllers.spec` and are importable from here too.
"""

from __future__ import annotations

import bisect
import copy
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from controllers.spec import MAX_LENGTH, SpecError, spec_number
from controllers.road.spline import spline_knots

_GL_T, _GL_W = np.polynomial.legendre.leggauss(10)
_GL_PAIRS = tuple(zip(_GL_T.tolist(), _GL_W.tolist()))
# _point's form of the pairs: 0.5 * (t_n + 1.0), the node's fraction of the interval, and w_n
_GL_FRACTIONS = tuple((0.5 * (tn + 1.0), wn) for tn, wn in _GL_PAIRS)
_GL_FRACTION_ARRAYS = tuple(np.array(column) for column in zip(*_GL_FRACTIONS))    # the compiled path's
MAX_TURN = 0.2          # rad of heading change per interval
MAX_INTERVAL = 2.0      # m per interval: also the coarse grid of projections
CLOSE_TOL = 1e-3        # m (and rad) a closed path may miss its start by
MAX_KNOTS = 1_000_000   # intervals of one path (a tight or long path needs many): memory bound
MAX_WAYPOINTS = 2_000   # the spline through them solves a dense system of this size


@dataclass(frozen=True)
class Projection:
    """A point projected on a path.

    Attributes:
        s: arc length of the foot point (in [0, L) for closed paths).
        lateral: signed offset of the point from the path, left positive.
        distance: Euclidean distance point to foot point.
        psi: path heading at the foot point.
        kappa: path curvature at the foot point.
        heading_error: wrapped (heading - psi) if a heading was given, else 0.
    """

    s: float
    lateral: float
    distance: float
    psi: float
    kappa: float
    heading_error: float


def wrap_angle(a):
    """Wrap an angle (or array of angles) to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


class Path:
    """A planar curve parameterised by arc length (see the module docstring)."""

    def __init__(self, s, x, y, psi, kappa0, kappa1, closed: bool = False):
        """Build from knots (s, x, y, psi: n+1 values) and per-interval end curvatures.

        Args:
            s: knot arc lengths, starting at 0, strictly increasing.
            x, y, psi: world position and heading at the knots.
            kappa0, kappa1: curvature at the start and end of each interval (n values).
            closed: the path is a loop (its last knot coincides with its first).
        """
        self.s = np.asarray(s, dtype=float)
        self.x = np.asarray(x, dtype=float)
        self.y = np.asarray(y, dtype=float)
        self.psi = np.asarray(psi, dtype=float)
        self.k0 = np.asarray(kappa0, dtype=float)
        self.k1 = np.asarray(kappa1, dtype=float)
        self.closed = bool(closed)
        ds = np.diff(self.s)
        if not (self.x.shape == self.y.shape == self.psi.shape == self.s.shape
                and self.k0.shape == self.k1.shape == ds.shape):
            raise SpecError("path knots: s, x, y, psi need n + 1 values and kappa0, kappa1 n values")
        if self.s.size < 2 or self.s[0] != 0.0 or np.any(ds <= 0):
            raise SpecError("path knots must start at s = 0 and strictly increase")
        if not all(np.all(np.isfinite(a)) for a in (self.s, self.x, self.y, self.psi, self.k0, self.k1)):
            raise SpecError("path has non-finite knot values")
        self._len = ds
        self._dk = (self.k1 - self.k0) / ds
        theta = self.k0 * ds + 0.5 * self._dk * ds ** 2
        ix, iy = self._integrate(np.arange(ds.size), ds)
        self._epsi = np.diff(self.psi) - theta
        self._ex = np.diff(self.x) - ix
        self._ey = np.diff(self.y) - iy
        self._lists = [a.tolist() for a in (self.s, self._len, self.psi, self.k0, self._dk, self.x,
                                            self._ex, self.y, self._ey, self._epsi)]
        self._length = float(self.s[-1])
        self._compiled: tuple | None = None     # (newton, point): with_compiled_search

    @property
    def length(self) -> float:
        """Total arc length L."""
        return self._length

    # ---- evaluation -----------------------------------------------------
    def _integrate(self, i: np.ndarray, u: np.ndarray):
        """Integral of (cos, sin) of the uncorrected heading over [s_i, s_i + u]."""
        v = 0.5 * (_GL_T[None, :] + 1.0) * u[:, None]
        ph = self.psi[i, None] + self.k0[i, None] * v + 0.5 * self._dk[i, None] * v ** 2
        half = 0.5 * u
        return half * (np.cos(ph) @ _GL_W), half * (np.sin(ph) @ _GL_W)

    def _locate(self, s: np.ndarray):
        """Interval index and local offset of arc lengths (already in [0, L])."""
        i = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, self._len.size - 1)
        return i, s - self.s[i]

    def evaluate(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """World (x, y, psi, kappa) at arc lengths s (scalar or array).

        Args:
            s: arc lengths; wrapped for closed paths, extended along the end
               tangents (kappa 0) beyond [0, L] for open ones.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if not np.all(np.isfinite(s)):
            raise SpecError(f"path evaluated at non-finite arc length {s[~np.isfinite(s)][0]}")
        inside = self.wrap(s) if self.closed else np.clip(s, 0.0, self.length)
        i, u = self._locate(inside)
        frac = u / self._len[i]
        ix, iy = self._integrate(i, u)
        x = self.x[i] + ix + frac * self._ex[i]
        y = self.y[i] + iy + frac * self._ey[i]
        psi = self.psi[i] + self.k0[i] * u + 0.5 * self._dk[i] * u ** 2 + frac * self._epsi[i]
        kappa = self.k0[i] + self._dk[i] * u
        if not self.closed:
            beyond = s - inside
            if np.any(beyond != 0.0):
                x = x + beyond * np.cos(psi)
                y = y + beyond * np.sin(psi)
                kappa = np.where(beyond != 0.0, 0.0, kappa)
        return x, y, psi, kappa

    def dkappa(self, s) -> np.ndarray:
        """Curvature derivative d kappa / ds at arc lengths s (0 beyond an open path's ends)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        inside = self.wrap(s) if self.closed else np.clip(s, 0.0, self.length)
        i, _ = self._locate(inside)
        return np.where(inside == s, self._dk[i], 0.0)

    def wrap(self, s):
        """Arc length modulo L (closed paths); unchanged for open paths."""
        if not self.closed:
            return s
        if type(s) is float:      # Python's % on floats is np.mod's algorithm (fmod, sign fix-up)
            return s % self._length
        return np.mod(s, self._length)

    # ---- projection -----------------------------------------------------
    def _candidates(self, s_guess: float | None, search: float) -> np.ndarray:
        """Knot indices to start the projection search from."""
        n = self.s.size - (1 if self.closed else 0)
        if s_guess is None:
            return np.arange(n)
        d = self._gap(self.s[:n], s_guess)
        idx = np.nonzero(np.abs(d) <= search)[0]
        return idx if idx.size else np.arange(n)

    def project(self, px: float, py: float, heading: float | None = None,
                s_guess: float | None = None, search: float = 30.0) -> Projection:
        """Project the point (px, py) on the path.

        Args:
            px, py: world position of the point.
            heading: optional heading of a vehicle at the point, for heading_error.
            s_guess: previous foot point (tracking): only knots within `search`
                metres of it are considered, which keeps the answer on the same
                branch where the path comes back near itself.
            search: half-width of the warm-start window, m.
        """
        if not (math.isfinite(px) and math.isfinite(py)):
            raise SpecError(f"cannot project non-finite point ({px}, {py})")
        # compiled: floats in (the interpreted path keeps numpy scalars' types through its arithmetic)
        newton, point = (self._compiled if self._compiled is not None and type(px) is float
                         and type(py) is float else (self._newton, self._point))
        s = None
        if s_guess is not None:                       # tracking: Newton from the previous foot point
            s = newton(px, py, float(s_guess))
            if s is not None and abs(self._gap(s, s_guess)) > search:
                s = None
        if s is None:
            idx = self._candidates(s_guess, search)
            k = idx[np.argmin((self.x[idx] - px) ** 2 + (self.y[idx] - py) ** 2)]
            s = newton(px, py, float(self.s[k]))
            s = float(self.s[k]) if s is None else s
        x, y, psi, kap = point(s)
        dx, dy = px - x, py - y
        herr = float(wrap_angle(heading - psi)) if heading is not None else 0.0
        return Projection(s=float(self.wrap(s)), lateral=-dx * math.sin(psi) + dy * math.cos(psi),
                          distance=math.hypot(dx, dy), psi=psi, kappa=kap, heading_error=herr)

    def with_compiled_search(self, kernel) -> "Path":
        """A copy of this path (sharing its arrays) whose project() runs the compiled Newton
        iteration and point evaluation of `kernel` (compiled_path.compiled_geometry()'s module:
        the bits of _newton and _point) for float coordinates."""
        knots = np.zeros((len(self._lists), self.s.size))     # the interval rows one shorter: 0 last
        for row, values in enumerate(self._lists):
            knots[row, :len(values)] = values
        shape = (knots, self.closed, self._length, _GL_FRACTION_ARRAYS[0], _GL_FRACTION_ARRAYS[1])
        newton = functools.partial(kernel.newton, *shape, MAX_INTERVAL)

        def compiled_newton(px: float, py: float, s: float) -> float | None:
            foot = newton(px, py, s)
            return None if foot != foot else foot       # NaN: no convergence, _newton's None

        path = copy.copy(self)
        path._compiled = compiled_newton, functools.partial(kernel.point, *shape)
        return path

    def _gap(self, s, s_ref: float):
        """s - s_ref (float or array), the short way round on a closed path."""
        d = s - s_ref
        return (d + 0.5 * self.length) % self.length - 0.5 * self.length if self.closed else d

    def _newton(self, px: float, py: float, s: float) -> float | None:
        """Foot point of (px, py) by Newton's method from s; None if it does not converge."""
        for _ in range(30):
            x, y, psi, kap = self._point(s)
            dx, dy = px - x, py - y
            f = dx * math.cos(psi) + dy * math.sin(psi)
            slope = 1.0 - kap * (-dx * math.sin(psi) + dy * math.cos(psi))
            step = f / slope if slope > 0.1 else f     # Newton, or a plain step near the centre
            s_new = s + min(max(step, -MAX_INTERVAL), MAX_INTERVAL)
            if not self.closed:
                s_new = min(max(s_new, 0.0), self.length)
            if abs(s_new - s) < 1e-10:
                return s_new
            s = s_new
        return None

    def _point(self, s: float) -> tuple[float, float, float, float]:
        """Scalar evaluate() without numpy overhead (the projection's inner loop)."""
        if self.closed:
            s = s % self.length
        beyond = 0.0
        if not self.closed and not 0.0 <= s <= self.length:
            beyond, s = (s, 0.0) if s < 0.0 else (s - self.length, self.length)
        sl = self._lists
        i = min(max(bisect.bisect_right(sl[0], s) - 1, 0), len(sl[1]) - 1)
        u = s - sl[0][i]
        psi_i, k0, dk = sl[2][i], sl[3][i], sl[4][i]
        cx = sy = 0.0
        half_dk, cos, sin = 0.5 * dk, math.cos, math.sin
        for fraction, wn in _GL_FRACTIONS:
            v = fraction * u                    # 0.5 * (tn + 1.0) * u
            ph = psi_i + k0 * v + half_dk * v * v
            cx += wn * cos(ph)
            sy += wn * sin(ph)
        frac = u / sl[1][i]
        x = sl[5][i] + 0.5 * u * cx + frac * sl[6][i]
        y = sl[7][i] + 0.5 * u * sy + frac * sl[8][i]
        psi = psi_i + k0 * u + 0.5 * dk * u * u + frac * sl[9][i]
        if beyond:
            return x + beyond * math.cos(psi), y + beyond * math.sin(psi), psi, 0.0
        return x, y, psi, k0 + dk * u

    # ---- derived paths --------------------------------------------------
    def offset(self, d: float) -> "Path":
        """The parallel path at lateral distance d (left positive), e.g. a lane centre.

        Args:
            d: lateral offset, m; must stay inside every radius of curvature.
        """
        kmax = np.maximum(np.abs(self.k0), np.abs(self.k1))
        if np.any(1.0 - d * np.concatenate([self.k0, self.k1]) <= 0.0):
            raise SpecError(f"offset {d} m crosses a centre of curvature (min radius "
                            f"{1.0 / kmax.max():.3f} m)")
        theta = self.k0 * self._len + 0.5 * self._dk * self._len ** 2
        s = np.concatenate([[0.0], np.cumsum(self._len - d * theta)])
        x = self.x - d * np.sin(self.psi)
        y = self.y + d * np.cos(self.psi)
        return Path(s, x, y, self.psi, self.k0 / (1 - d * self.k0), self.k1 / (1 - d * self.k1),
                    closed=self.closed)

    # ---- constructors ---------------------------------------------------
    @classmethod
    def from_pieces(cls, pieces: Sequence[tuple[float, float, float]], x0: float = 0.0,
                    y0: float = 0.0, psi0: float = 0.0, closed: bool = False) -> "Path":
        """Integrate pieces (length, kappa_start, kappa_end) of linear curvature.

        Args:
            pieces: each a length > 0 and its start and end curvature.
            x0, y0, psi0: start pose.
            closed: check that the end meets the start (within CLOSE_TOL) and wrap s.
        """
        lens, k0s, k1s = [], [], []
        total = sum(length for length, _, _ in pieces)
        if not total <= MAX_LENGTH:
            raise SpecError(f"path of {total:g} m is longer than {MAX_LENGTH:g} m")
        need = [max(max(abs(ka), abs(kb)) * length / MAX_TURN, length / MAX_INTERVAL)
                for length, ka, kb in pieces]
        if not sum(need) <= MAX_KNOTS:
            raise SpecError(f"path too winding: its curvature needs {sum(need):.3g} intervals "
                            f"(at most {MAX_KNOTS}); is a radius far too small?")
        for (length, ka, kb), count in zip(pieces, need):
            n = max(1, int(np.ceil(count)))
            edges = np.linspace(0.0, 1.0, n + 1)
            lens.extend(np.full(n, length / n))
            k0s.extend(ka + (kb - ka) * edges[:-1])
            k1s.extend(ka + (kb - ka) * edges[1:])
        return cls._integrated(np.array(lens), np.array(k0s), np.array(k1s), x0, y0, psi0, closed)

    @classmethod
    def _integrated(cls, lens, k0, k1, x0, y0, psi0, closed) -> "Path":
        """Knots by exact integration of piecewise-linear curvature."""
        n = lens.size
        s = np.concatenate([[0.0], np.cumsum(lens)])
        x, y, psi = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
        x[0], y[0], psi[0] = x0, y0, psi0
        psi[1:] = psi0 + np.cumsum(k0 * lens + 0.5 * (k1 - k0) * lens)
        probe = cls(s, np.zeros(n + 1), np.zeros(n + 1), psi, k0, k1)
        ix, iy = probe._integrate(np.arange(n), lens)
        x[1:] = x0 + np.cumsum(ix)
        y[1:] = y0 + np.cumsum(iy)
        if closed:
            gap = float(np.hypot(x[-1] - x[0], y[-1] - y[0]))
            turn = psi[-1] - psi[0]
            twists = round(turn / (2 * np.pi))
            if gap > CLOSE_TOL or abs(turn - 2 * np.pi * twists) > CLOSE_TOL or twists == 0:
                raise SpecError(f"closed path does not close: end misses start by {gap:.4f} m "
                                f"and {np.degrees(turn - 2 * np.pi * twists):.4f} deg "
                                f"(total turn {np.degrees(turn):.3f} deg)")
            x[-1], y[-1], psi[-1] = x[0], y[0], psi[0] + 2 * np.pi * twists
        return cls(s, x, y, psi, k0, k1, closed=closed)

    @classmethod
    def from_curvature(cls, s, kappa, x0: float = 0.0, y0: float = 0.0, psi0: float = 0.0,
                       closed: bool = False) -> "Path":
        """A path whose curvature is the piecewise-linear interpolation of (s, kappa).

        Args:
            s: strictly increasing stations starting at 0, m.
            kappa: curvature at the stations, 1/m.
            x0, y0, psi0: start pose; closed: as in `from_pieces`.
        """
        s, kappa = np.asarray(s, dtype=float), np.asarray(kappa, dtype=float)
        if s.ndim != 1 or s.shape != kappa.shape or s.size < 2 or s[0] != 0 or np.any(np.diff(s) <= 0):
            raise SpecError("curvature profile needs equal-length s and kappa lists, "
                            "s starting at 0 and strictly increasing")
        return cls.from_pieces(list(zip(np.diff(s), kappa[:-1], kappa[1:])), x0, y0, psi0, closed)

    @classmethod
    def from_waypoints(cls, points, closed: bool = False, samples_per_span: int = 16) -> "Path":
        """A C2 cubic spline through waypoints (chord-length parameter), resampled.

        Args:
            points: (n, 2) world positions; for a closed path do not repeat the first.
            closed: periodic spline and wrapping s.
            samples_per_span: knots per spline span.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim >= 1 and points.shape[0] > MAX_WAYPOINTS:
            raise SpecError(f"{points.shape[0]} waypoints, more than {MAX_WAYPOINTS}")
        s, x, y, psi, kappa = spline_knots(points, closed, samples_per_span)
        return cls(s, x, y, psi, kappa[:-1], kappa[1:], closed=closed)

    @classmethod
    def from_spec(cls, spec: Mapping, where: str = "path") -> "Path":
        """Build a path from its YAML form.

        Args:
            spec: one of
                {segments: [{line: L}, {arc: {radius: R, angle: deg}},
                            {arc: {length: L, radius: R}}, {clothoid: {length: L,
                            kappa_start: k0, kappa_end: k1}}, ...]},
                {curvature: {s: [...], kappa: [...]}},
                {waypoints: [[x, y], ...]},
                each with optional start: {x, y, heading_deg} and closed: bool.
                Arc angles and radii are signed positive to the left: in the
                angle form the sign of the angle gives the direction and the
                radius is > 0; in the length form the radius carries the sign.
            where: the spec's location, for error messages.
        """
        return _path_from_spec(spec, where)


def _segment_piece(seg, where: str) -> tuple[float, float, float]:
    """(length, kappa_start, kappa_end) of one {line|arc|clothoid: ...} segment."""
    if not isinstance(seg, Mapping) or len(seg) != 1:
        raise SpecError(f"{where}: a segment is a one-key mapping line/arc/clothoid, got {seg!r}")
    (kind, body), = seg.items()
    if kind not in ("line", "arc", "clothoid"):
        raise SpecError(f"{where}: unknown segment kind {kind!r} (line, arc, clothoid)")
    w = f"{where}.{kind}"
    if kind == "line":
        return spec_number(body, w, positive=True), 0.0, 0.0
    if not isinstance(body, Mapping):
        raise SpecError(f"{w}: expected a mapping, got {body!r}")
    if kind == "arc":
        if set(body) == {"radius", "angle"}:
            radius = spec_number(body["radius"], w + ".radius", positive=True)
            angle = np.radians(spec_number(body["angle"], w + ".angle"))
            if angle == 0:
                raise SpecError(f"{w}.angle: must not be 0")
            return radius * abs(angle), np.sign(angle) / radius, np.sign(angle) / radius
        if set(body) == {"length", "radius"}:
            radius = spec_number(body["radius"], w + ".radius")
            if radius == 0:
                raise SpecError(f"{w}.radius: must not be 0")
            return spec_number(body["length"], w + ".length", positive=True), 1 / radius, 1 / radius
        raise SpecError(f"{w}: expected keys {{radius, angle}} or {{length, radius}}, got {sorted(body)}")
    if set(body) != {"length", "kappa_start", "kappa_end"}:
        raise SpecError(f"{w}: expected keys length, kappa_start, kappa_end, got {sorted(body)}")
    return (spec_number(body["length"], w + ".length", positive=True),
            spec_number(body["kappa_start"], w + ".kappa_start"), spec_number(body["kappa_end"], w + ".kappa_end"))


def _path_from_spec(spec, where: str) -> Path:
    """Implementation of Path.from_spec."""
    if not isinstance(spec, Mapping):
        raise SpecError(f"{where}: expected a mapping, got {spec!r}")
    forms = [k for k in ("segments", "curvature", "waypoints") if k in spec]
    extra = set(spec) - {"segments", "curvature", "waypoints", "start", "closed"}
    if len(forms) != 1 or extra:
        raise SpecError(f"{where}: needs exactly one of segments/curvature/waypoints "
                        f"(plus start, closed); got keys {sorted(spec)}")
    closed = spec.get("closed", False)
    if not isinstance(closed, bool):
        raise SpecError(f"{where}.closed: expected true/false, got {closed!r}")
    start = spec.get("start", {})
    if not isinstance(start, Mapping) or set(start) - {"x", "y", "heading_deg"}:
        raise SpecError(f"{where}.start: expected a mapping with x, y, heading_deg, got {start!r}")
    x0 = spec_number(start.get("x", 0.0), where + ".start.x")
    y0 = spec_number(start.get("y", 0.0), where + ".start.y")
    psi0 = np.radians(spec_number(start.get("heading_deg", 0.0), where + ".start.heading_deg"))
    form = forms[0]
    body = spec[form]
    try:
        if form == "segments":
            if not isinstance(body, Sequence) or isinstance(body, str) or not body:
                raise SpecError(f"{where}.segments: expected a non-empty list")
            pieces = [_segment_piece(seg, f"{where}.segments[{i}]") for i, seg in enumerate(body)]
            return Path.from_pieces(pieces, x0, y0, psi0, closed)
        if form == "curvature":
            if not isinstance(body, Mapping) or set(body) != {"s", "kappa"}:
                raise SpecError(f"{where}.curvature: expected a mapping with lists s and kappa")
            return Path.from_curvature(body["s"], body["kappa"], x0, y0, psi0, closed)
        if "start" in spec:
            raise SpecError(f"{where}.start: not used with waypoints (they fix the start)")
        return Path.from_waypoints(body, closed)
    except SpecError as exc:
        msg = str(exc)
        raise SpecError(msg if msg.startswith(where) else f"{where}.{form}: {msg}") from None
    except (TypeError, ValueError) as exc:
        raise SpecError(f"{where}.{form}: {exc}") from None
