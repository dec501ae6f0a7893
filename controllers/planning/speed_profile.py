"""Low-energy reference speed along a path: v(s) and a(s) = v dv/ds.

Works on u = v^2 / 2 over a uniform grid in arc length, where the limits are
simple: u <= v_lim^2 / 2 with v_lim = min(v_max, sqrt(a_lat_max / |kappa|)),
the longitudinal acceleration is a = du/ds, and the jerk is v d^2u/ds^2.

1. Forward and backward passes bound du/ds by a_max and -d_max (the classic
   acceleration-limited envelope, starting / ending at 0 when asked).
2. Jerk: a min filter of half-width W/2 followed by a moving average of width
   W. Every value of the average comes from minima over windows that contain
   the point itself, so the result stays below the envelope (below every
   limit); averaging keeps |du/ds| within the same bounds and makes
   |d^2u/ds^2| <= 2 A / W with A = max(a_max, d_max). With
   W = 2 v_max A / j_max the jerk v d^2u/ds^2 is then at most j_max.

3. Stop: the smoothing alone ends as u ~ (s_stop - s)^2, i.e. v proportional
   to the distance left, which a follower never covers (v decays
   exponentially). So from the strongest deceleration of the final braking on,
   a jerk-limited final segment (controllers.planning.speed_stop: jerk -j, constant
   -d_max, then +j until a = 0 exactly when v = 0) replaces the tail; the
   smoothing is redone with its stop moved a few metres on, so that the two
   meet where the segment ends exactly at s_stop. v reaches 0 at s_stop in
   finite time with |a| <= d_max and |jerk| <= j_max (v ~ (s_stop - s)^(2/3)
   in the last phase). If that segment would break a curve's speed limit, it
   takes over at a low speed instead (JOIN_SPEED_RANGE).
   `SpeedProfile.final_from` says where it starts.

Starting from rest the profile has v = 0 and a = 0 at its first point, and it
leaves it only as v ~ s: a vehicle sitting exactly there would wait forever,
so the planner puts the profile's start a little behind the vehicle.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from controllers.planning import speed_stop
from controllers.spec import SpecError, spec_number

V_LIMIT = 50.0 / 3.6   # the paper's domain: below 50 km/h
# The final stop segment takes over below d_max^2 / j_max, clipped to these speeds (m/s): high
# enough for the 0.5 m grid to resolve the tail, low enough that no road curve limits it.
JOIN_SPEED_RANGE = (1.0, 3.0)


@dataclass(frozen=True)
class SpeedLimits:
    """Comfort limits of the reference speed (SI units).

    Attributes:
        v_max: top speed, < 50 km/h (13.89 m/s).
        a_lat_max: lateral acceleration bound in curves, v^2 |kappa|.
        a_max: longitudinal acceleration bound.
        d_max: longitudinal deceleration bound (positive number).
        j_max: longitudinal jerk bound.
    """

    v_max: float = 12.0
    a_lat_max: float = 2.0
    a_max: float = 1.0
    d_max: float = 1.5
    j_max: float = 1.0

    def __post_init__(self):
        for f in fields(self):
            spec_number(getattr(self, f.name), f"speed.{f.name}", positive=True)
        if self.v_max >= V_LIMIT:
            raise SpecError(f"speed.v_max: must stay below 50 km/h ({V_LIMIT:.3f} m/s), got {self.v_max}")

    @classmethod
    def from_spec(cls, spec, where: str = "speed") -> "SpeedLimits":
        """Read {v_max, a_lat_max, a_max, d_max, j_max} (all optional) from YAML."""
        if spec is None:
            return cls()
        if not isinstance(spec, Mapping):
            raise SpecError(f"{where}: expected a mapping, got {spec!r}")
        known = {f.name for f in fields(cls)}
        if set(spec) - known:
            raise SpecError(f"{where}: unknown keys {sorted(set(spec) - known)} (known: {sorted(known)})")
        try:
            return cls(**{k: spec_number(v, f"{where}.{k}", positive=True) for k, v in spec.items()})
        except SpecError as exc:
            raise SpecError(str(exc).replace("speed.", f"{where}.", 1)) from None


@dataclass(frozen=True)
class SpeedProfile:
    """Reference speed and acceleration on a uniform arc-length grid.

    Attributes:
        s: grid, m (uniform spacing).
        v: reference speed, m/s.
        a: reference acceleration v dv/ds, m/s^2.
        final_from: where the final stop segment (controllers.planning.speed_stop) takes
            over, or None (no stop, or no join found: the smoothed tail is kept).
        final_state: (v, a) at final_from, the segment's initial state, or None.
    """

    s: np.ndarray
    v: np.ndarray
    a: np.ndarray
    final_from: float | None = None
    final_state: tuple[float, float] | None = None

    def at(self, s) -> tuple[np.ndarray, np.ndarray]:
        """(v, a) at arc lengths s, linearly interpolated, held beyond the ends.

        Args:
            s: arc lengths (scalar or array) in the grid's coordinates.
        """
        s = np.asarray(s, dtype=float)
        v = np.interp(s, self.s, self.v)
        a = np.interp(s, self.s, self.a)
        out = (s < self.s[0]) | (s > self.s[-1])
        return v, np.where(out, 0.0, a)


def _passes(u_lim: np.ndarray, up: float, down: float) -> np.ndarray:
    """Largest u <= u_lim with u[i+1] - u[i] in [-down, up] (forward then backward)."""
    u = u_lim.copy()
    for i in range(1, u.size):
        u[i] = min(u[i], u[i - 1] + up)
    for i in range(u.size - 2, -1, -1):
        u[i] = min(u[i], u[i + 1] + down)
    return u


def _smooth(u: np.ndarray, half: int, left: float | None, right: float | None) -> np.ndarray:
    """Min filter (half-width `half`) then moving average (width 2 half + 1).

    Args:
        u: values to smooth.
        half: half-width in samples.
        left, right: the value u holds beyond each end (None: the end value).
    """
    lpad = np.full(2 * half, u[0] if left is None else left)
    rpad = np.full(2 * half, u[-1] if right is None else right)
    padded = np.concatenate([lpad, u, rpad])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    eroded = windows.min(axis=1)                      # length n + 2 half
    csum = np.concatenate([[0.0], np.cumsum(eroded)])
    width = 2 * half + 1
    return (csum[width:] - csum[:-width]) / width


def _smoothed_u(kappa: np.ndarray, ds: float, limits: SpeedLimits, start_from_rest: bool,
                stop_at_end: bool, v_start: float | None) -> np.ndarray:
    """u = v^2/2 on the grid: limits, acceleration passes, jerk smoothing (module docstring)."""
    with np.errstate(divide="ignore"):
        v_lim = np.minimum(limits.v_max, np.sqrt(limits.a_lat_max / np.abs(kappa)))
    u_lim = 0.5 * v_lim ** 2
    if start_from_rest:
        u_lim[0] = 0.0
    elif v_start is not None:
        u_lim[0] = min(u_lim[0], 0.5 * v_start ** 2)
    if stop_at_end:
        u_lim[-1] = 0.0
    u = _passes(u_lim, limits.a_max * ds, limits.d_max * ds)
    big = max(limits.a_max, limits.d_max)
    half = int(np.ceil(limits.v_max * big / limits.j_max / ds))
    u = _smooth(u, half, 0.0 if start_from_rest else None, 0.0 if stop_at_end else None)
    u = np.maximum(u, 0.0)
    if start_from_rest:
        u[0] = 0.0
    if stop_at_end:
        u[-1] = 0.0
    return u


def _stopping(kappa: np.ndarray, ds: float, limits: SpeedLimits, start_from_rest: bool,
              v_start: float | None, s0: float) -> SpeedProfile | None:
    """The profile that stops at its last point through the final segment
    (controllers.planning.speed_stop), or None if no join point was found.

    First choice: the segment takes over where the final braking is strongest,
    so the deceleration stays there (up to d_max) and is released only at the
    end. If that segment would be too fast for a curve near the stop, it takes
    over at a low speed instead (see JOIN_SPEED_RANGE).
    """
    found = _stop_with(kappa, ds, limits, start_from_rest, v_start, s0, None)
    if found is not None:
        with np.errstate(divide="ignore"):
            v_lim = np.minimum(limits.v_max, np.sqrt(limits.a_lat_max / np.abs(kappa)))
        if np.all(found.v <= v_lim + 1e-9):
            return found
    j, d = limits.j_max, limits.d_max
    v_join_max = min(max(d * d / j, JOIN_SPEED_RANGE[0]), JOIN_SPEED_RANGE[1])
    return _stop_with(kappa, ds, limits, start_from_rest, v_start, s0, v_join_max)


def _stop_with(kappa: np.ndarray, ds: float, limits: SpeedLimits, start_from_rest: bool,
               v_start: float | None, s0: float, v_join_max: float | None) -> SpeedProfile | None:
    """_stopping with one choice of join region (speed_stop.join_point's v_join_max).

    The smoothing is redone with its stop moved on by a whole number of grid
    steps until the final segment meets it (once or twice in practice).
    """
    n, j, d = kappa.size, limits.j_max, limits.d_max
    s_stop = s0 + ds * (n - 1)
    extra = 0
    for _ in range(4):
        grid_kappa = np.concatenate([kappa, np.full(extra, kappa[-1])])
        u = _smoothed_u(grid_kappa, ds, limits, start_from_rest, True, v_start)
        a = np.gradient(u, ds)
        s = s0 + ds * np.arange(u.size)
        s_join = speed_stop.join_point(s, u, a, s_stop, j, d, v_join_max)
        if s_join is not None:
            v, a, state = speed_stop.splice(s, u, a, s_join, s_stop, j, d)
            return SpeedProfile(s=s[:n], v=v[:n], a=a[:n], final_from=s_join, final_state=state)
        more = speed_stop.missing_shift(s, u, a, s_stop, j, d, v_join_max)
        if more is None:
            return None
        extra += max(1, int(np.floor(more / ds)))
    return None


def plan_speed(kappa, ds: float, limits: SpeedLimits, start_from_rest: bool = True,
               stop_at_end: bool = True, s0: float = 0.0, v_start: float | None = None) -> SpeedProfile:
    """The reference speed profile along a path (see the module docstring).

    Args:
        kappa: path curvature on the uniform grid s0 + i ds (at least 2 points).
        ds: grid spacing, m.
        limits: comfort limits.
        start_from_rest: v = 0 at the first point (else v_start, or the limit there).
        stop_at_end: v = 0 at the last point and beyond, reached in finite time.
        s0: arc length of the first point.
        v_start: speed at the first point when not starting from rest (None: free).
    """
    kappa = np.asarray(kappa, dtype=float)
    if kappa.ndim != 1 or kappa.size < 2 or not np.all(np.isfinite(kappa)):
        raise SpecError("speed profile: curvature must be a finite array of at least 2 points")
    ds = spec_number(ds, "speed profile ds", positive=True)
    if v_start is not None and not start_from_rest:
        v_start = spec_number(v_start, "v_start")
    s = s0 + ds * np.arange(kappa.size)
    if stop_at_end:
        found = _stopping(kappa, ds, limits, start_from_rest, v_start, s0)
        if found is not None:
            return found
    u = _smoothed_u(kappa, ds, limits, start_from_rest, stop_at_end, v_start)
    return SpeedProfile(s=s, v=np.sqrt(2.0 * u), a=np.gradient(u, ds))
