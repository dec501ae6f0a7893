"""The end of a stop: a jerk-limited final segment that reaches v = 0 in finite time.

The smoothed profile of controllers.planning.speed_profile ends as u = v^2/2 ~ (s_stop - s)^2,
so v ~ distance left: a vehicle following it approaches the stop point
exponentially and never arrives. The final segment replaces that tail with a
time-domain manoeuvre from the state (v1, a1 <= 0) where it joins the profile:

    phase 1: jerk -j until a = a_p            (tau_1 = (a1 - a_p) / j)
    phase 2: a = a_p = -d, if needed           (tau_2)
    phase 3: jerk +j until a = 0, when v = 0   (tau_3 = -a_p / j)

with a_p = -min(sqrt(a1^2 / 2 + j v1), d): the two-phase solution of v = 0 and
a = 0 at the end, capped at the deceleration bound. In the last phase
v = (j/2) tau^2 and the distance left is j tau^3 / 6, so v ~ (distance
left)^(2/3) and the stop point is reached after tau_1 + tau_2 + tau_3 seconds.

The join point is where the distance left equals the segment's length,
searched from the strongest deceleration of the final braking on (or, when
the caller asks, below a join speed). The smoothed tail is slower than the
segment would be there (the segment from it stops short), so the caller redoes
the smoothing with its stop moved on (`missing_shift`) until the two meet.
"""

from __future__ import annotations

import math

import numpy as np

SAMPLES = 4001     # time samples of the final segment, for the s -> (v, a) lookup


def segment_phases(v1, a1, j: float, d: float):
    """Durations and jerks of the final segment's three phases (arrays accepted).

    Args:
        v1: speed at the join, m/s (>= a1^2 / (2 j)); a1: acceleration there, <= 0, m/s^2.
        j: jerk bound, m/s^3; d: deceleration bound, m/s^2 (>= |a1|).

    Returns:
        ((tau_1, tau_2, tau_3), (-j, 0, +j)): phase 2 (constant -d) lasts 0 unless
        the two-phase peak sqrt(a1^2/2 + j v1) would exceed d.
    """
    v1, a1 = np.asarray(v1, dtype=float), np.asarray(a1, dtype=float)
    a_p = -np.minimum(np.sqrt(0.5 * a1 * a1 + j * v1), d)
    tau1 = (a1 - a_p) / j
    v_peak = v1 + a1 * tau1 - 0.5 * j * tau1 * tau1
    tau2 = np.maximum(v_peak - 0.5 * a_p * a_p / j, 0.0) / -a_p
    return (tau1, tau2, -a_p / j), (-j, 0.0, j)


def _advance(x, v, a, jerk, tau):
    """State (x, v, a) after time tau at constant jerk."""
    return (x + v * tau + 0.5 * a * tau * tau + jerk * tau ** 3 / 6.0,
            v + a * tau + 0.5 * jerk * tau * tau, a + jerk * tau)


def segment_length(v1, a1, j: float, d: float):
    """Distance the final segment covers from (v1, a1) to rest (arrays accepted).

    Args:
        v1: speed at the join, m/s; a1: acceleration there, m/s^2.
        j: jerk bound, m/s^3; d: deceleration bound, m/s^2.
    """
    taus, jerks = segment_phases(v1, a1, j, d)
    state = (0.0, np.asarray(v1, dtype=float), np.asarray(a1, dtype=float))
    for tau, jerk in zip(taus, jerks):
        state = _advance(*state, jerk, tau)
    return state[0]


def segment_samples(v1: float, a1: float, j: float, d: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time, distance from the join, speed and acceleration along the final segment.

    Args:
        v1: speed at the join, m/s; a1: acceleration there, m/s^2.
        j: jerk bound, m/s^3; d: deceleration bound, m/s^2.

    Returns:
        (t, x, v, a) at SAMPLES instants from the join to rest; x increases.
    """
    taus, jerks = segment_phases(v1, a1, j, d)
    ends = np.cumsum([float(tau) for tau in taus])
    t = np.linspace(0.0, ends[-1], SAMPLES)
    x, v, a = np.zeros_like(t), np.full_like(t, v1), np.full_like(t, a1)
    start, state = 0.0, (0.0, float(v1), float(a1))
    for end, tau, jerk in zip(ends, taus, jerks):
        inside = (t >= start) & (t <= end)
        x[inside], v[inside], a[inside] = _advance(*state, jerk, t[inside] - start)
        state, start = _advance(*state, jerk, float(tau)), end
    v[-1], a[-1] = 0.0, 0.0          # exactly at rest (rounding leaves ~1e-16)
    return t, x, np.maximum(v, 0.0), a


def _tail_start(s: np.ndarray, a: np.ndarray, v: np.ndarray, s_stop: float,
                v_join_max: float | None) -> int:
    """First index of the tail where the final segment may take over.

    With v_join_max None: the last point of strongest deceleration in the final
    braking (the run of a < 0 that ends at s_stop). Else: the first point after
    the last one faster than v_join_max.
    """
    if v_join_max is not None:
        fast = np.nonzero(v > v_join_max)[0]
        return int(fast[-1]) + 1 if fast.size else 0
    last = int(np.nonzero(s <= s_stop)[0][-1])
    coasting = np.nonzero(a[:last + 1] >= 0.0)[0]
    first = int(coasting[-1]) + 1 if coasting.size else 0
    if first > last:
        return s.size
    braking = a[first:last + 1]
    return first + int(np.nonzero(braking <= braking.min() + 1e-9)[0][-1])


def _tail_gaps(s: np.ndarray, u: np.ndarray, a: np.ndarray, s_stop: float, j: float, d: float,
               v_join_max: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the profile's tail where a join may be, and their gaps.

    The tail runs from _tail_start up to s_stop. A point is usable if v > 0 and
    j v >= a^2 / 2 (else the segment would need negative phase times). Its gap
    is the distance left minus the segment's length: >= 0 means the segment
    from there stops short of s_stop (or exactly at it).
    """
    v = np.sqrt(2.0 * np.maximum(u, 0.0))
    a1 = np.minimum(a, 0.0)
    idx = np.arange(_tail_start(s, a, v, s_stop, v_join_max), s.size)
    idx = idx[s[idx] <= s_stop]
    idx = idx[(v[idx] > 0.0) & (j * v[idx] >= 0.5 * a1[idx] ** 2)]
    gap = (s_stop - s[idx]) - segment_length(v[idx], a1[idx], j, d)
    return idx, gap


def join_point(s: np.ndarray, u: np.ndarray, a: np.ndarray, s_stop: float, j: float, d: float,
               v_join_max: float | None) -> float | None:
    """Arc length where the final segment from the profile's state ends exactly at s_stop.

    Finds the first two consecutive usable tail points (see _tail_gaps) whose gaps
    go from >= 0 to < 0, then bisects between them on the linearly interpolated profile.

    Args:
        s, u, a: the profile's grid, u = v^2/2 and a = du/ds (may run past s_stop).
        s_stop: the stop point.
        j, d: jerk and deceleration bounds.
        v_join_max: highest speed allowed at the join; None: from the strongest
            deceleration of the final braking on.

    Returns:
        The join's arc length, or None if the gaps never change sign.
    """
    idx, gap = _tail_gaps(s, u, a, s_stop, j, d, v_join_max)
    change = np.nonzero((gap[:-1] >= 0.0) & (gap[1:] < 0.0) & (np.diff(idx) == 1))[0]
    if change.size == 0:
        return None
    lo, hi = float(s[idx[change[0]]]), float(s[idx[change[0]] + 1])

    def g(x: float) -> float:
        ux, ax = np.interp(x, s, u), min(float(np.interp(x, s, a)), 0.0)
        return (s_stop - x) - float(segment_length(math.sqrt(2.0 * max(ux, 0.0)), ax, j, d))

    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) >= 0.0 else (lo, mid)
    return lo


def splice(s: np.ndarray, u: np.ndarray, a: np.ndarray, s_join: float, s_stop: float,
           j: float, d: float) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """Speed and acceleration on the grid s with the final segment from s_join to s_stop.

    Args:
        s, u, a: the profile's grid, u = v^2/2 and a = du/ds.
        s_join: where the segment starts (from join_point); s_stop: where it ends.
        j, d: jerk and deceleration bounds.

    Returns:
        (v, a) on s: the profile before s_join, the segment after, 0 from s_stop
        on; and (v1, a1), the segment's initial state.
    """
    v1 = math.sqrt(2.0 * max(float(np.interp(s_join, s, u)), 0.0))
    a1 = min(float(np.interp(s_join, s, a)), 0.0)
    _, x, v_seg, a_seg = segment_samples(v1, a1, j, d)
    x *= (s_stop - s_join) / x[-1]   # the bisection leaves ~1e-12 m: end exactly at the stop
    v, a = np.sqrt(2.0 * np.maximum(u, 0.0)), a.copy()
    after = s > s_join
    v[after] = np.interp(s[after] - s_join, x, v_seg, right=0.0)
    a[after] = np.interp(s[after] - s_join, x, a_seg, right=0.0)
    v[s >= s_stop], a[s >= s_stop] = 0.0, 0.0
    return v, a, (v1, a1)


def missing_shift(s: np.ndarray, u: np.ndarray, a: np.ndarray, s_stop: float, j: float, d: float,
                  v_join_max: float | None) -> float | None:
    """How much further on the smoothed tail must move for the final segment to meet it.

    At the tail's first usable point (the fastest, see _tail_gaps) the distance
    left exceeds the segment's length by its gap; moving the tail on by that
    much (and no more) brings the gap there to about zero.

    Args:
        s, u, a: the profile's grid, u = v^2/2 and a = du/ds.
        s_stop: the stop point; j, d: jerk and deceleration bounds; v_join_max: highest join speed.

    Returns:
        The shift in metres, or None when the tail has no usable point or no gap.
    """
    idx, gap = _tail_gaps(s, u, a, s_stop, j, d, v_join_max)
    return float(gap[0]) if idx.size and gap[0] > 0.0 else None
